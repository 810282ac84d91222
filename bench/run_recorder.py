"""The run's recording, written as the run goes (calbench-recording/1, in chunks).

:class:`RunRecorder` sits between the sequencer and :class:`bench.recording.RecordingWriter`:
it converts DAQ time to the recording clock, appends every sample block, makes a chunk
durable (flush + fsync) once ``chunk_s`` of data *and* ``min_chunk_wall_s`` of wall time
have gathered, and closes windows (flush, then the segment is added to the sidecar
atomically). Only after that are observers told, so what the database says is complete is
always on disk.

Recording clock: ``t = t_daq − t_daq0 + t_offset``; a fresh run starts at 0, a resumed run
continues one sample period after the last row kept.

A write that fails (disk full, an I/O error) cuts the CSV back to the last durable chunk, so
no torn row stays, and raises an ``OSError`` naming the file, what failed and where it was
cut; nothing more is written (the run ends ERROR with the table made safe).

Window metadata the format has no column for (kind, pose, means) is kept in the sidecar's
``calbench_windows`` list beside ``segments`` (:mod:`bench.run_sidecar`), so a resumed run
can rebuild its record from the files alone.

Sample gaps: ``t_daq`` is the DAQ's sample counter over its rate, so a gap leaves its hole
in the time axis by itself; :meth:`RunRecorder.record_gap` also writes where it is (rows
before it, time stamps on either side, the lost sequence numbers) into the sidecar's
``calbench_gaps`` list as it happens. A gap before the first block of a DAQ epoch pins the
clock's origin to the first lost sample, and a DAQ restart re-bases the clock where the next
sample was due plus the samples lost across it, so every hole stays in the time axis.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bench.recording.model import Segment, Sidecar
from bench.recording.writer import RecordingWriter
from bench.records import ChunkRecord, DwellChoice, GapRecord, WindowRecord
from bench.run_sidecar import (
    GAPS_KEY,
    RUN_KEY,
    WINDOWS_KEY,
    gap_from_json,
    gap_to_json,
    window_from_json,
    window_to_json,
)


class RunRecorder:
    """Incremental writer of one run's recording.

    Build with :meth:`create` (fresh run) or :meth:`resume` (after a crash).

    :param chunk_s: data per durable chunk on the recording clock (s).
    :param min_chunk_wall_s: minimum wall time between chunk flushes (s), so a fast
        simulation does not turn every block into an fsync and a database write.
    """

    def __init__(
        self,
        writer: RecordingWriter,
        n_rows: int,
        last_t_s: float | None,
        chunk_seq: int,
        windows: list[WindowRecord],
        chunk_s: float = 1.0,
        min_chunk_wall_s: float = 0.2,
    ) -> None:
        self.writer = writer
        self.csv_path = Path(writer.csv_path)
        self.n_rows = n_rows
        self.last_t_s = last_t_s
        self.chunk_seq = chunk_seq
        self.windows = windows
        self.held_s: list[float] = [0.0] * len(windows)
        """Per window: recording-clock time the run had spent held by its end (s)."""
        self.chunk_s = chunk_s
        self.min_chunk_wall_s = min_chunk_wall_s
        self._t_offset = 0.0 if last_t_s is None else last_t_s + 1.0 / writer.sidecar.sample_rate_hz
        self._t_daq0: float | None = None
        self._expect_t_s: float | None = None  # set by a gap: where the next row is due
        self._chunk_first = n_rows
        self._chunk_t0: float | None = None
        self._last_flush_wall = time.monotonic()
        self.failed: OSError | None = None
        self.durable_end_byte = self.csv_path.stat().st_size  # everything so far is flushed
        self.durable_rows = n_rows
        self._durable_t_s = last_t_s
        raw_gaps = writer.sidecar.extra.get(GAPS_KEY, [])
        kept = [gap_from_json(g) for g in raw_gaps] if isinstance(raw_gaps, list) else []
        self.gaps: list[GapRecord] = [g for g in kept if g.after_row <= n_rows]
        if len(self.gaps) != len(kept):  # gaps after the rows a resume kept are gone with them
            self._write_gaps()

    # -- construction --------------------------------------------------------------------

    @classmethod
    def create(
        cls, csv_path: str | Path, sidecar: Sidecar, has_temp: bool, run_meta: dict[str, object], **kw: float
    ) -> RunRecorder:
        """Start a new recording (refuses to overwrite one)."""
        n_axes = len(sidecar.table.axes) if sidecar.table is not None else 0
        extra = {**sidecar.extra, RUN_KEY: run_meta, WINDOWS_KEY: [], GAPS_KEY: []}
        Path(csv_path).parent.mkdir(parents=True, exist_ok=True)
        first = dataclasses.replace(sidecar, segments=(), extra=extra)
        writer = RecordingWriter(csv_path, first, n_axes, has_temp)
        return cls(writer, 0, None, 0, [], **kw)

    @classmethod
    def resume(
        cls, csv_path: str | Path, keep_end_byte: int | None, next_window: int, chunk_seq: int, **kw: float
    ) -> RunRecorder:
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
        meta = writer.sidecar.extra.get(WINDOWS_KEY, [])
        if not isinstance(meta, list):
            raise ValueError(f"{path}: sidecar entry {WINDOWS_KEY!r} is not a list")
        if len(segs) < next_window or len(meta) < next_window:
            raise ValueError(
                f"{path}: the sidecar holds {len(segs)} windows, cannot resume at window {next_window}"
            )
        windows = [window_from_json(meta[i], segs[i]) for i in range(next_window)]
        if state.last_t_s is not None and windows and windows[-1].end_s > state.last_t_s:
            raise ValueError(
                f"{path}: window {next_window - 1} ends at {windows[-1].end_s} s "
                f"but the kept rows end at {state.last_t_s} s"
            )
        rec = cls(writer, state.n_rows, state.last_t_s, chunk_seq, windows, **kw)
        rec.held_s = [float(meta[i].get("held_s", 0.0)) for i in range(next_window)]  # 0: older files
        rec._set_sidecar_windows(segs[:next_window], windows)
        return rec

    @property
    def run_meta(self) -> dict[str, object]:
        """The ``calbench_run`` entry of the sidecar (run id, procedure parameters, dwell...)."""
        meta = self.writer.sidecar.extra.get(RUN_KEY, {})
        if not isinstance(meta, dict):
            raise ValueError(f"{self.writer.csv_path}: sidecar entry {RUN_KEY!r} is not an object")
        return dict(meta)

    def update_run_meta(self, **values: object) -> None:
        """Merge values into the sidecar's ``calbench_run`` entry (rewritten atomically)."""
        meta = {**self.run_meta, **values}
        self.writer.sidecar = dataclasses.replace(
            self.writer.sidecar, extra={**self.writer.sidecar.extra, RUN_KEY: meta}
        )
        self._io("writing the sidecar", self.writer.set_segments, self.writer.sidecar.segments or ())

    def record_dwell(self, dwell: DwellChoice) -> None:
        """Store the dwell choice with the recording."""
        self.update_run_meta(dwell=dataclasses.asdict(dwell))

    # -- samples -------------------------------------------------------------------------

    def to_recording_time(self, t_daq_s: np.ndarray) -> np.ndarray:
        """DAQ time stamps -> recording clock (s)."""
        if self._t_daq0 is None:
            self._t_daq0 = float(t_daq_s[0])
        return t_daq_s - self._t_daq0 + self._t_offset

    def rebase(self, n_lost: int = 0) -> None:
        """The DAQ clock restarted: the next block is stamped where the next sample was
        expected, plus ``n_lost`` sample periods (samples known lost across the restart)."""
        self._t_offset = self._next_t_s() + n_lost / self.writer.sidecar.sample_rate_hz
        self._t_daq0 = None

    def _next_t_s(self) -> float:
        """Recording time of the next sample the DAQ is expected to deliver."""
        if self._expect_t_s is not None:
            return self._expect_t_s
        if self.last_t_s is not None:
            return self.last_t_s + 1.0 / self.writer.sidecar.sample_rate_hz
        return self._t_offset

    def record_gap(
        self,
        *,
        first_lost_seq: int | None,
        n_lost: int | None,
        cause: str,
        window_index: int | None,
        window_label: str,
        action: str,
        daq_epoch: int,
        restart: bool = False,
    ) -> GapRecord:
        """Record a gap where it happens (sidecar rewritten atomically) and return it.

        Call it when the gap is met in the stream, before the first block after it. The
        gap's time stamps are on the recording clock: the next sample is stamped
        ``t_resume_s = t_expected_s + n_lost / fs``, where ``t_expected_s`` is where the
        first lost sample would have been (consecutive gaps add up). ``restart``: the DAQ's
        clock restarted, the clock is re-based at ``t_resume_s`` (:meth:`rebase`).
        """
        fs = self.writer.sidecar.sample_rate_hz
        lost = n_lost or 0
        t_expected = self._next_t_s()
        if self._t_daq0 is None and not restart and first_lost_seq is not None:
            # No block of this DAQ epoch yet: pin the clock's origin to the first lost sample,
            # so the first row keeps its distance from where the samples should have started.
            self._t_daq0 = first_lost_seq / fs
            self._t_offset = t_expected
        t_resume = t_expected + lost / fs
        gap = GapRecord(
            first_lost_seq=first_lost_seq,
            n_lost=n_lost,
            cause=cause,
            after_row=self.n_rows,
            t_last_s=self.last_t_s,
            t_resume_s=t_resume,
            window_index=window_index,
            window_label=window_label,
            action=action,
            daq_epoch=daq_epoch,
        )
        self.gaps.append(gap)
        if restart:
            self.rebase(lost)
        self._expect_t_s = t_resume
        self._write_gaps()
        return gap

    def _write_gaps(self) -> None:
        extra = {**self.writer.sidecar.extra, GAPS_KEY: [gap_to_json(g) for g in self.gaps]}
        self.writer.sidecar = dataclasses.replace(self.writer.sidecar, extra=extra)
        self._io("writing the sidecar", self.writer.set_segments, self.writer.sidecar.segments or ())

    def append(
        self,
        t_s: np.ndarray,
        accel: np.ndarray,
        table_deg: np.ndarray | None,
        temp_c: np.ndarray | None,
        window_index: int | None,
    ) -> ChunkRecord | None:
        """Append samples (``t_s`` already on the recording clock); return a chunk if one became durable."""
        if t_s.size == 0:
            return None
        self._io("appending samples", self.writer.append, t_s, accel, table_deg, temp_c)
        self.n_rows += int(t_s.size)
        self.last_t_s = float(t_s[-1])
        self._expect_t_s = None
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
        self._io("flushing a chunk", self.writer.flush)
        end_byte = Path(self.writer.csv_path).stat().st_size
        self.durable_end_byte, self.durable_rows, self._durable_t_s = end_byte, self.n_rows, self.last_t_s
        chunk = ChunkRecord(
            seq=self.chunk_seq,
            first_sample=self._chunk_first,
            n_samples=self.n_rows - self._chunk_first,
            last_t_s=self.last_t_s,
            end_byte=end_byte,
            window_index=window_index,
        )
        self.chunk_seq += 1
        self._chunk_first = self.n_rows
        self._chunk_t0 = None
        self._last_flush_wall = time.monotonic()
        return chunk

    # -- windows -------------------------------------------------------------------------

    def _set_sidecar_windows(self, segs: list[Segment], windows: list[WindowRecord]) -> None:
        held = self.held_s
        extra = {
            **self.writer.sidecar.extra,
            WINDOWS_KEY: [window_to_json(w, h) for w, h in zip(windows, held, strict=True)],
        }
        self.writer.sidecar = dataclasses.replace(self.writer.sidecar, extra=extra)
        self._io("writing the sidecar", self.writer.set_segments, segs)

    def close_window(self, window: WindowRecord, held_s: float = 0.0) -> ChunkRecord | None:
        """Flush the samples, then add the window's segment to the sidecar (atomic rewrite).

        :param held_s: recording-clock time the run had spent held (paused, suspended) by the
            window's end (s), kept so a resumed run counts its working time from the file.

        :returns: the chunk flushed with it, if samples were pending.
        """
        chunk = self.flush_chunk(window.index)
        segs = [*(self.writer.sidecar.segments or ()), Segment(window.start_s, window.end_s, window.label)]
        self.windows.append(window)
        self.held_s.append(held_s)
        self._set_sidecar_windows(segs, self.windows)
        return chunk

    def close(self) -> ChunkRecord | None:
        """Flush what is pending and close the files (after a write failure: nothing more is
        written, the recording stays cut at its last durable chunk)."""
        if self.failed is not None:
            return None
        chunk = self.flush_chunk(None)
        self._io("closing the recording", self.writer.close)
        return chunk

    # -- write failures ------------------------------------------------------------------

    def _io(self, what: str, fn: Callable[..., object], *args: object) -> None:
        """Run a write; an ``OSError`` (disk full, I/O error) cuts the recording at its last
        durable chunk and is raised again, naming the file, what failed and where it was cut."""
        if self.failed is not None:
            why = self.failed.strerror or self.failed
            raise OSError(
                self.failed.errno,
                f"{self.csv_path}: the recording failed earlier ({why}); nothing more is written",
            )
        try:
            fn(*args)
        except OSError as exc:
            self.failed = exc
            self._cut_to_durable()
            raise OSError(
                exc.errno,
                f"{self.csv_path}: {what} failed ({exc.strerror or exc}); the recording "
                f"is cut at its last durable chunk ({self.durable_rows} rows, "
                f"{self.durable_end_byte} bytes)",
            ) from exc

    def _cut_to_durable(self) -> None:
        """Close the CSV and truncate it to the last durable chunk (a torn row never stays)."""
        f = self.writer._file
        with contextlib.suppress(OSError, ValueError):
            f.close()  # may fail flushing its buffer: the cut below removes whatever got out
        self.writer._closed = True
        with contextlib.suppress(OSError), self.csv_path.open("r+b") as out:
            out.truncate(self.durable_end_byte)
            out.flush()
            os.fsync(out.fileno())
        with contextlib.suppress(OSError):  # a half-written temporary sidecar
            (self.csv_path.parent / f".{self.writer.sidecar_path.name}.tmp").unlink(missing_ok=True)
        self.n_rows, self.last_t_s = self.durable_rows, self._durable_t_s
        self._chunk_first = self.n_rows
