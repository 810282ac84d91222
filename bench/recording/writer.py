"""Write calbench-recording/1, incrementally while the bench records, or all at once.

:class:`RecordingWriter` appends sample blocks to the CSV; :meth:`RecordingWriter.flush`
flushes and ``fsync``s, so a crash loses at most the rows appended since. The sidecar is
written when the writer opens and rewritten atomically (temporary file, ``fsync``,
``os.replace``) whenever segments change, so it is never half-written.
:meth:`RecordingWriter.resume` reopens a recording after a crash: it cuts a torn last
line (and any zero bytes a crash left behind) and continues after the last complete row.
:func:`write_recording` writes a whole :class:`Recording` through the same code.

Floats are written with Python's shortest round-trip representation (``repr``), so
reading the file back gives bit-identical arrays; a block is formatted by one C-level
operation (:func:`bench.recording.rows.format_block`).
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import BinaryIO, NamedTuple

import numpy as np
import numpy.typing as npt

from bench.recording.errors import RecordingError
from bench.recording.model import Recording, Segment, Sidecar
from bench.recording.reader import (
    ACCEL_COLUMNS,
    GYRO_COLUMNS,
    TEMP_COLUMN,
    TIME_COLUMN,
    read_header,
    read_sidecar,
    sidecar_path_for,
    table_columns,
)
from bench.recording.rows import format_block, format_rows_with_extras
from bench.recording.sidecar import check_segments_disjoint, sidecar_to_dict


def _write_json_atomic(path: Path, obj: object) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", encoding="utf-8") as f:
        json.dump(obj, f, indent=1, ensure_ascii=False)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # platforms without directory handles
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


class ResumeState(NamedTuple):
    """What :meth:`RecordingWriter.resume` found: the writer, complete rows kept, last time stamp (s)."""

    writer: RecordingWriter
    n_rows: int
    last_t_s: float | None


class RecordingWriter:
    """Append-only writer of one recording (CSV + sidecar).

    :param csv_path: the CSV to create; the sidecar goes beside it with the same stem.
    :param sidecar: units, geometry and (initial) segments.
    :param n_axes: number of table axes (must equal ``len(sidecar.table.axes)``, 0 without a table).
    :param has_temp: write a ``temp`` column.
    :param has_gyro: write ``gx, gy, gz`` (the sidecar must name ``gyro_unit``).
    :param extra_columns: names of further columns, written after the known ones as text.
    :param overwrite: replace an existing recording; by default an existing file is an error,
        so a finished run is never clobbered.
    """

    def __init__(
        self,
        csv_path: str | Path,
        sidecar: Sidecar,
        n_axes: int,
        has_temp: bool,
        *,
        has_gyro: bool = False,
        extra_columns: Sequence[str] = (),
        overwrite: bool = False,
    ) -> None:
        table_axes = len(sidecar.table.axes) if sidecar.table is not None else 0
        if n_axes != table_axes:
            raise ValueError(f"n_axes = {n_axes} but the sidecar's table has {table_axes} axes")
        if has_gyro and sidecar.gyro_unit is None:
            raise ValueError("gyro columns need sidecar.gyro_unit ('rad/s' or 'deg/s')")
        columns = [TIME_COLUMN, *ACCEL_COLUMNS, *table_columns(n_axes)]
        if has_temp:
            columns.append(TEMP_COLUMN)
        if has_gyro:
            columns.extend(GYRO_COLUMNS)
        for c in extra_columns:
            if c in columns or c.startswith("table_") or not c:
                raise ValueError(f"extra column name {c!r} is empty or clashes with a format column")
        columns.extend(extra_columns)
        path = Path(csv_path)
        if not overwrite and path.exists():
            raise FileExistsError(f"{path}: recording exists; refusing to overwrite it")
        self._init(path, sidecar, columns, n_axes, has_temp, has_gyro, list(extra_columns), None)
        self._file = path.open("w", encoding="utf-8", newline="")
        csv.writer(self._file, lineterminator="\n").writerow(columns)
        self._write_sidecar()
        self.flush()

    def _init(
        self,
        path: Path,
        sidecar: Sidecar,
        columns: list[str],
        n_axes: int,
        has_temp: bool,
        has_gyro: bool,
        extras: list[str],
        last_t: float | None,
    ) -> None:
        self.csv_path = path
        self.sidecar_path = sidecar_path_for(path)
        self.sidecar = sidecar
        self.columns = columns
        self.n_axes = n_axes
        self.has_temp = has_temp
        self.has_gyro = has_gyro
        self.extra_columns = extras
        self.last_t_s = last_t
        self.n_rows = 0
        self._closed = False

    # -- samples ---------------------------------------------------------------------------

    def append(
        self,
        t_s: npt.ArrayLike,
        accel: npt.ArrayLike,
        table_deg: npt.ArrayLike | None = None,
        temp_c: npt.ArrayLike | None = None,
        *,
        gyro: npt.ArrayLike | None = None,
        extra: dict[str, Sequence[str]] | None = None,
    ) -> None:
        """Append a block of samples.

        :param t_s: (n,) time stamps (s), strictly increasing, after the last one written.
        :param accel: (n, 3) raw ax, ay, az in ``channel_unit``.
        :param table_deg: (n, n_axes) encoder angles (deg), as read (wrapped is fine).
        :param temp_c: (n,) temperature (°C); NaN writes an empty (missing) field.
        :param gyro: (n, 3) raw gyro channels; NaN writes an empty field.
        :param extra: column name -> n strings, for the writer's extra columns.
        :raises ValueError: wrong shapes, non-finite required values, time not increasing.
        """
        if self._closed:
            raise ValueError(f"{self.csv_path}: writer is closed")
        t = np.asarray(t_s, dtype=float).reshape(-1)
        n = t.shape[0]
        a = np.asarray(accel, dtype=float)
        if a.shape != (n, 3):
            raise ValueError(f"accel has shape {a.shape}, expected ({n}, 3)")
        n_req = 4 + self.n_axes
        block = np.empty((n, len(self.columns) - len(self.extra_columns)))
        block[:, 0] = t
        block[:, 1:4] = a
        if self.n_axes:
            if table_deg is None:
                raise ValueError(f"table_deg is required: the recording has {self.n_axes} table axes")
            q = np.asarray(table_deg, dtype=float).reshape(n, -1) if n else np.zeros((0, self.n_axes))
            if q.shape != (n, self.n_axes):
                raise ValueError(f"table_deg has shape {q.shape}, expected ({n}, {self.n_axes})")
            block[:, 4:n_req] = q
        elif table_deg is not None:
            raise ValueError("table_deg given but the recording has no table")
        finite = np.isfinite(block[:, :n_req]).all(axis=1)
        if not finite.all():
            bad = int(np.flatnonzero(~finite)[0])
            raise ValueError(f"non-finite t, accel or table value in sample {bad} of the block")
        after_last = self.last_t_s is None or not n or t[0] > self.last_t_s
        if not after_last or (n > 1 and np.any(t[1:] <= t[:-1])):
            raise ValueError(
                f"time stamps must increase strictly (last written: {self.last_t_s}, "
                f"block starts at {t[0]!r})"
            )
        col = n_req
        if self.has_temp:
            block[:, col] = self._column(temp_c, (n,), "temp_c")
            col += 1
        elif temp_c is not None:
            raise ValueError("temp_c given but the writer has no temp column")
        if self.has_gyro:
            block[:, col : col + 3] = self._column(gyro, (n, 3), "gyro")
        elif gyro is not None:
            raise ValueError("gyro given but the writer has no gyro columns")
        if self.extra_columns:
            self._file.write(format_rows_with_extras(block, self.extra_columns, extra or {}))
        else:
            self._file.write(format_block(block))
        if n:
            self.last_t_s = float(t[-1])
            self.n_rows += n

    @staticmethod
    def _column(values: npt.ArrayLike | None, shape: tuple[int, ...], name: str) -> np.ndarray:
        if values is None:
            raise ValueError(f"{name} is required by this writer's columns")
        v = np.asarray(values, dtype=float).reshape(shape)
        if np.any(np.isinf(v)):
            raise ValueError(f"{name} has infinite values")
        return v

    def flush(self) -> None:
        """Flush the CSV to the operating system and ``fsync`` it to disk."""
        if not self._closed:
            self._file.flush()
            os.fsync(self._file.fileno())

    # -- segments --------------------------------------------------------------------------

    def set_segments(self, segments: Sequence[Segment]) -> None:
        """Replace the sidecar's segments (validated disjoint) and rewrite the sidecar atomically."""
        segs = tuple(segments)
        for s in segs:
            if not (math.isfinite(s.start_s) and math.isfinite(s.end_s) and s.end_s > s.start_s):
                raise ValueError(
                    f"segment {s.label!r}: need finite start_s < end_s, got {s.start_s}, {s.end_s}"
                )
        check_segments_disjoint(segs, self.sidecar_path)
        extra = {k: v for k, v in self.sidecar.extra.items() if k != "segments"}
        self.sidecar = dataclasses.replace(self.sidecar, segments=segs, extra=extra)
        self._write_sidecar()

    def add_segment(self, segment: Segment) -> None:
        """Append one segment and rewrite the sidecar atomically."""
        self.set_segments((*(self.sidecar.segments or ()), segment))

    def _write_sidecar(self) -> None:
        _write_json_atomic(self.sidecar_path, sidecar_to_dict(self.sidecar))

    # -- life cycle ------------------------------------------------------------------------

    def close(self) -> None:
        """Flush, ``fsync`` and close; safe to call twice."""
        if not self._closed:
            self.flush()
            self._file.close()
            self._closed = True

    def abandon(self) -> None:
        """Close without writing what is still buffered (after a write failed: a full disk);
        the file keeps what reached it. Safe to call twice."""
        if not self._closed:
            self._closed = True
            with contextlib.suppress(OSError):
                self._file.close()  # its flush fails again; the file is closed all the same

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    @classmethod
    def resume(cls, csv_path: str | Path) -> ResumeState:
        """Reopen a recording for appending after a crash.

        Cuts everything after the last complete line (a torn line, zero bytes a crash left).
        The last complete line must have one field per header column and a numeric ``t``;
        otherwise nothing is cut and a :class:`RecordingError` names the line.

        :returns: the writer (appending after the last row), the number of data rows kept
            and the last time stamp (``None`` if no rows).
        """
        path = Path(csv_path)
        sc = read_sidecar(sidecar_path_for(path))
        names = read_header(path)
        n_axes = len(sc.table.axes) if sc.table is not None else 0
        known = {TIME_COLUMN, *ACCEL_COLUMNS, *table_columns(n_axes), TEMP_COLUMN, *GYRO_COLUMNS}
        has_gyro = "gx" in names
        extras = [c for c in names if c not in known]
        with path.open("rb") as f:
            size = f.seek(0, os.SEEK_END)
            keep, last_line = _last_complete_line(f, size)
        rows_before = _count_newlines(path, keep)
        if rows_before == 0:
            raise RecordingError(path, "no complete header line to resume after", line=1)
        last_t: float | None = None
        n_rows = rows_before - 1
        if n_rows:
            fields = next(csv.reader([last_line.decode("utf-8", errors="replace")]))
            try:
                last_t = float(fields[names.index(TIME_COLUMN)])
            except (ValueError, IndexError):
                last_t = math.nan
            if len(fields) != len(names) or not math.isfinite(last_t):
                raise RecordingError(
                    path,
                    f"last complete line is not a valid row ({len(fields)} fields, "
                    f"expected {len(names)} with a numeric t); not resuming",
                    row=n_rows,
                    line=rows_before,
                )
        if keep < size:
            with path.open("r+b") as f:
                f.truncate(keep)
                f.flush()
                os.fsync(f.fileno())
        w = cls.__new__(cls)
        w._init(path, sc, names, n_axes, TEMP_COLUMN in names, has_gyro, extras, last_t)
        w.n_rows = n_rows
        w._file = path.open("a", encoding="utf-8", newline="")
        return ResumeState(w, n_rows, last_t)


def _last_complete_line(f: BinaryIO, size: int) -> tuple[int, bytes]:
    """(offset just after the last b"\\n" once trailing NUL bytes are ignored, that last complete line)."""
    block = 1 << 16
    end = size
    tail = b""
    while True:
        start = max(0, end - block)
        f.seek(start)
        tail = f.read(end - start) + tail
        usable = tail.rstrip(b"\x00")
        cut = usable.rfind(b"\n")
        prev = usable.rfind(b"\n", 0, cut) if cut >= 0 else -1
        if (cut >= 0 and prev >= 0) or start == 0:
            keep = start + cut + 1 if cut >= 0 else 0
            return keep, usable[prev + 1 : cut].rstrip(b"\r") if cut >= 0 else b""
        end = start


def _count_newlines(path: Path, limit: int) -> int:
    n = 0
    with path.open("rb") as f:
        remaining = limit
        while remaining > 0 and (chunk := f.read(min(1 << 22, remaining))):
            n += chunk.count(b"\n")
            remaining -= len(chunk)
    return n


def write_recording(rec: Recording, csv_path: str | Path, *, overwrite: bool = False) -> None:
    """Write a whole recording (CSV + sidecar) through :class:`RecordingWriter`.

    :param rec: the recording; its arrays are validated as for an append.
    :param csv_path: the CSV path; the sidecar gets the same stem.
    :param overwrite: replace existing files.
    """
    n_axes = rec.table_deg.shape[1] if rec.table_deg is not None else 0
    extras = list(rec.extra_columns)
    with RecordingWriter(
        csv_path,
        rec.sidecar,
        n_axes,
        rec.temp_c is not None,
        has_gyro=rec.gyro_raw is not None,
        extra_columns=extras,
        overwrite=overwrite,
    ) as w:
        chunk = 100_000
        for i in range(0, rec.n_samples, chunk):
            sl = slice(i, i + chunk)
            w.append(
                rec.t_s[sl],
                rec.accel_raw[sl],
                rec.table_deg[sl] if rec.table_deg is not None else None,
                rec.temp_c[sl] if rec.temp_c is not None else None,
                gyro=rec.gyro_raw[sl] if rec.gyro_raw is not None else None,
                extra={k: v[sl] for k, v in rec.extra_columns.items()} if extras else None,
            )
