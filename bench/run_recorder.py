"""The run's recording, written as the run goes (calbench-recording/1, in chunks).

:class:`RunRecorder` sits between the sequencer and :class:`bench.recording.RecordingWriter`:
it converts DAQ time to the recording clock, appends every sample block, makes a chunk
durable (flush + fsync) once ``chunk_s`` of data *and* ``min_chunk_wall_s`` of wall time
have gathered, and closes windows (flush, then the segment is added to the sidecar
atomically). Only after that are observers told, so what the database says is complete is
always on disk.

Recording clock: ``t = t_daq − t_daq0 + t_offset``; a fresh run starts at 0, a resumed run
continues one sample period after the last row kept.

A failed write (a full disk, an I/O error) ends the recording where it was last durable:
the CSV is cut back to the last durable chunk's end (never a torn last row) and the error is
raised with what was kept, so the sequencer ends the run as ERROR with the table made safe;
the database's chunk rows describe exactly the file that is left.

Window metadata the format has no column for (kind, pose, means) is kept in the sidecar's
``calbench_windows`` list beside ``segments``, so a resumed run can rebuild its record from
the files alone.
"""

from __future__ import annotations

import dataclasses
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.recording.model import Segment, Sidecar
from bench.recording.writer import RecordingWriter
from bench.records import ChunkRecord, DwellChoice, WindowKind, WindowRecord

WINDOWS_KEY = "calbench_windows"
RUN_KEY = "calbench_run"


def _window_to_json(w: WindowRecord) -> dict[str, object]:
    d = dataclasses.asdict(w)
    d["kind"] = w.kind.value
    return d


def _window_from_json(d: dict[str, Any], seg: Segment) -> WindowRecord:
    return WindowRecord(
        index=int(d["index"]), label=seg.label, kind=WindowKind(d["kind"]), start_s=seg.start_s,
        end_s=seg.end_s, n_samples=int(d["n_samples"]), pose_deg=tuple(d["pose_deg"]),
        mean_table_deg=tuple(d["mean_table_deg"]), temp_c_mean=float(d["temp_c_mean"]),
        step_index=int(d["step_index"]), means=dict(d.get("means", {})),
    )


class RunRecorder:
    """Incremental writer of one run's recording.

    Build with :meth:`create` (fresh run) or :meth:`resume` (after a crash).

    :param chunk_s: data per durable chunk on the recording clock (s).
    :param min_chunk_wall_s: minimum wall time between chunk flushes (s), so a fast
        simulation does not turn every block into an fsync and a database write.
    """

    def __init__(self, writer: RecordingWriter, n_rows: int, last_t_s: float | None, chunk_seq: int,
                 windows: list[WindowRecord], chunk_s: float = 1.0, min_chunk_wall_s: float = 0.2) -> None:
        self.writer = writer
        self.csv_path = Path(writer.csv_path)
        self.n_rows = n_rows
        self.last_t_s = last_t_s
        self.chunk_seq = chunk_seq
        self.windows = windows
        self.chunk_s = chunk_s
        self.min_chunk_wall_s = min_chunk_wall_s
        self._t_offset = 0.0 if last_t_s is None else last_t_s + 1.0 / writer.sidecar.sample_rate_hz
        self._t_daq0: float | None = None
        self._chunk_first = n_rows
        self._chunk_t0: float | None = None
        self._last_flush_wall = time.monotonic()
        self.failed: OSError | None = None
        writer.flush()  # the header (or the rows kept by a resume) is the first durable end
        self._durable_end_byte = self.csv_path.stat().st_size
        self._durable_rows = n_rows

    # -- construction --------------------------------------------------------------------

    @classmethod
    def create(cls, csv_path: str | Path, sidecar: Sidecar, has_temp: bool, run_meta: dict[str, object],
               **kw: float) -> RunRecorder:
        """Start a new recording (refuses to overwrite one)."""
        n_axes = len(sidecar.table.axes) if sidecar.table is not None else 0
        extra = {**sidecar.extra, RUN_KEY: run_meta, WINDOWS_KEY: []}
        Path(csv_path).parent.mkdir(parents=True, exist_ok=True)
        first = dataclasses.replace(sidecar, segments=(), extra=extra)
        writer = RecordingWriter(csv_path, first, n_axes, has_temp)
        return cls(writer, 0, None, 0, [], **kw)

    @classmethod
    def resume(cls, csv_path: str | Path, keep_end_byte: int | None, next_window: int, chunk_seq: int,
               **kw: float) -> RunRecorder:
        """Reopen after a crash: cut the CSV at ``keep_end_byte``, keep windows ``< next_window``.

        :param keep_end_byte: the last durable chunk's end (bytes); ``None`` keeps every
            complete row (the writer still cuts a torn last line).
        :param next_window: first window to record again; later segments are dropped.
        :param chunk_seq: number of the next chunk.
        :raises ValueError: the sidecar holds fewer windows than ``next_window``.
        """
        path = Path(csv_path)
        if keep_end_byte is not None and path.stat().st_size > keep_end_byte:
            with path.open("r+b") as f:
                f.truncate(keep_end_byte)
                f.flush()
                os.fsync(f.fileno())
        state = RecordingWriter.resume(path)
        writer = state.writer
        segs = list(writer.sidecar.segments or ())
        meta = list(writer.sidecar.extra.get(WINDOWS_KEY, []))  # type: ignore[call-overload]
        if len(segs) < next_window or len(meta) < next_window:
            raise ValueError(f"{path}: the sidecar holds {len(segs)} windows, "
                             f"cannot resume at window {next_window}")
        windows = [_window_from_json(meta[i], segs[i]) for i in range(next_window)]
        if state.last_t_s is not None and windows and windows[-1].end_s > state.last_t_s:
            raise ValueError(f"{path}: window {next_window - 1} ends at {windows[-1].end_s} s "
                             f"but the kept rows end at {state.last_t_s} s")
        rec = cls(writer, state.n_rows, state.last_t_s, chunk_seq, windows, **kw)
        rec._set_sidecar_windows(segs[:next_window], windows)
        return rec

    @property
    def run_meta(self) -> dict[str, object]:
        """The ``calbench_run`` entry of the sidecar (run id, procedure parameters, dwell...)."""
        return dict(self.writer.sidecar.extra.get(RUN_KEY, {}))  # type: ignore[call-overload]

    def update_run_meta(self, **values: object) -> None:
        """Merge values into the sidecar's ``calbench_run`` entry (rewritten atomically)."""
        meta = {**self.run_meta, **values}
        self.writer.sidecar = dataclasses.replace(self.writer.sidecar,
                                                  extra={**self.writer.sidecar.extra, RUN_KEY: meta})
        self.writer.set_segments(self.writer.sidecar.segments or ())

    def record_dwell(self, dwell: DwellChoice) -> None:
        """Store the dwell choice with the recording."""
        self.update_run_meta(dwell=dataclasses.asdict(dwell))

    # -- samples -------------------------------------------------------------------------

    def to_recording_time(self, t_daq_s: np.ndarray) -> np.ndarray:
        """DAQ time stamps -> recording clock (s)."""
        if self._t_daq0 is None:
            self._t_daq0 = float(t_daq_s[0])
        return t_daq_s - self._t_daq0 + self._t_offset

    def rebase(self) -> None:
        """The DAQ clock restarted: the next block continues one sample period after the last row."""
        if self.last_t_s is not None:
            self._t_offset = self.last_t_s + 1.0 / self.writer.sidecar.sample_rate_hz
        self._t_daq0 = None

    def append(self, t_s: np.ndarray, accel: np.ndarray, table_deg: np.ndarray | None,
               temp_c: np.ndarray | None, window_index: int | None) -> ChunkRecord | None:
        """Append samples (``t_s`` already on the recording clock); return a chunk if one became durable."""
        if t_s.size == 0:
            return None
        self._check_usable()
        try:
            self.writer.append(t_s, accel, table_deg, temp_c)
        except OSError as exc:
            raise self._cut_after(exc) from exc
        self.n_rows += int(t_s.size)
        self.last_t_s = float(t_s[-1])
        if self._chunk_t0 is None:
            self._chunk_t0 = float(t_s[0])
        enough_data = self.last_t_s - self._chunk_t0 >= self.chunk_s
        if enough_data and time.monotonic() - self._last_flush_wall >= self.min_chunk_wall_s:
            return self.flush_chunk(window_index)
        return None

    def flush_chunk(self, window_index: int | None) -> ChunkRecord | None:
        """Make everything appended so far durable; ``None`` if nothing was pending."""
        if self.n_rows == self._chunk_first or self.last_t_s is None:
            return None
        self._check_usable()
        try:
            self.writer.flush()
        except OSError as exc:
            raise self._cut_after(exc) from exc
        end_byte = Path(self.writer.csv_path).stat().st_size
        self._durable_end_byte, self._durable_rows = end_byte, self.n_rows
        chunk = ChunkRecord(seq=self.chunk_seq, first_sample=self._chunk_first,
                            n_samples=self.n_rows - self._chunk_first, last_t_s=self.last_t_s,
                            end_byte=end_byte, window_index=window_index)
        self.chunk_seq += 1
        self._chunk_first = self.n_rows
        self._chunk_t0 = None
        self._last_flush_wall = time.monotonic()
        return chunk

    # -- windows -------------------------------------------------------------------------

    def _set_sidecar_windows(self, segs: list[Segment], windows: list[WindowRecord]) -> None:
        extra = {**self.writer.sidecar.extra, WINDOWS_KEY: [_window_to_json(w) for w in windows]}
        self.writer.sidecar = dataclasses.replace(self.writer.sidecar, extra=extra)
        self.writer.set_segments(segs)

    def close_window(self, window: WindowRecord) -> ChunkRecord | None:
        """Flush the samples, then add the window's segment to the sidecar (atomic rewrite).

        :returns: the chunk flushed with it, if samples were pending.
        """
        chunk = self.flush_chunk(window.index)
        segs = [*(self.writer.sidecar.segments or ()), Segment(window.start_s, window.end_s, window.label)]
        self.windows.append(window)
        self._set_sidecar_windows(segs, self.windows)
        return chunk

    def close(self) -> ChunkRecord | None:
        """Flush what is pending and close the files (after a failed write: nothing more)."""
        if self.failed is not None:
            return None
        chunk = self.flush_chunk(None)
        self.writer.close()
        return chunk

    # -- failed writes -------------------------------------------------------------------

    def _check_usable(self) -> None:
        if self.failed is not None:
            raise OSError(self.failed.errno, f"recording {self.csv_path} was cut after a failed write")

    def _cut_after(self, exc: OSError) -> OSError:
        """Abandon the writer's buffer and cut the CSV to the last durable chunk; the error to raise."""
        self.failed = exc
        self.writer.abandon()
        end = self._durable_end_byte
        try:
            with self.csv_path.open("r+b") as f:
                f.truncate(end)
                f.flush()
                os.fsync(f.fileno())
            kept = f"cut at the last durable chunk: {self._durable_rows} samples, {end} bytes"
        except OSError as cut_exc:
            kept = f"could not be cut to the last durable chunk ({end} bytes): {cut_exc}"
        self.n_rows = self._durable_rows
        reason = exc.strerror or str(exc)
        return OSError(exc.errno, f"writing {self.csv_path} failed ({reason}); the recording was {kept}")
