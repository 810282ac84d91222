"""A disk that fills in the middle of a run: the run ends ERROR naming the file and the
cause, the table is made safe, and the recording is cut at its last durable chunk (no torn
row), so it reads back and resumes like any interrupted recording."""

from __future__ import annotations

import errno
from pathlib import Path
from typing import Any

import pytest

from bench.recording.reader import read_recording
from bench.run_recorder import RunRecorder
from bench.run_state import Outcome
from tests.bench.sequencer.test_sequencer import make, quick_static

pytestmark = pytest.mark.timeout(120)


class FillingFile:
    """A text file that takes ``budget`` more characters, then writes part of a row and fails
    with ENOSPC, as a full disk does (every later write and flush fails too)."""

    def __init__(self, real: Any, budget: int) -> None:
        self.real = real
        self.left = budget
        self.full = False

    def write(self, text: str) -> int:
        if self.full or len(text) > self.left:
            part = text[: max(0, self.left)]
            if part:
                self.real.write(part)
                self.real.flush()  # the torn part reaches the file
            self.left = 0
            self.full = True
            raise OSError(errno.ENOSPC, "No space left on device")
        self.left -= len(text)
        return int(self.real.write(text))

    def flush(self) -> None:
        if self.full:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.real.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.real, name)


def test_disk_full_mid_run_ends_error_with_the_table_safe_and_the_recording_cut(tmp_path: Path) -> None:
    seq, table, _, obs, _ = make(tmp_path, quick_static())
    csv = tmp_path / "run.csv"
    # room for about five windows of the twelve (a window of 1 s is ~200 rows of ~90 bytes)
    seq.recorder.writer._file = FillingFile(seq.recorder.writer._file, 5 * 200 * 90)
    acq = seq.run()
    assert acq.outcome is Outcome.ERROR and acq.resumable  # a full disk resumes once cleared
    assert "No space left on device" in (acq.error or "") and str(csv) in (acq.error or "")
    assert "cut at its last durable chunk" in (acq.error or "")
    assert table.stops >= 1  # safe state
    last = obs.chunks[-1]  # the last chunk the observers were told is durable
    assert csv.stat().st_size == last.end_byte
    assert acq.n_samples == last.first_sample + last.n_samples
    rec = read_recording(csv)  # no torn row: every row parses, times increase
    assert rec.n_samples == acq.n_samples
    assert len(rec.sidecar.segments or ()) == len(acq.windows) == len(obs.windows)
    assert 2 <= len(acq.windows) < 12
    # ...and it resumes like a crashed recording, at the window after the last complete one
    resumed = RunRecorder.resume(csv, last.end_byte, len(acq.windows), last.seq + 1)
    assert resumed.n_rows == acq.n_samples and len(resumed.windows) == len(acq.windows)
    resumed.close()


def test_a_failed_sidecar_write_is_a_failure_too(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    seq, table, _, obs, _ = make(tmp_path, quick_static())
    writer = seq.recorder.writer
    real = writer.set_segments
    calls = {"n": 0}

    def failing(segments: Any) -> None:
        calls["n"] += 1
        if calls["n"] == 4:
            raise OSError(errno.EIO, "Input/output error")
        real(segments)

    monkeypatch.setattr(writer, "set_segments", failing)
    acq = seq.run()
    assert acq.outcome is Outcome.ERROR and "Input/output error" in (acq.error or "")
    assert table.stops >= 1
    # the window's chunk was flushed before its segment failed: durable, though no observer heard of it
    size = (tmp_path / "run.csv").stat().st_size
    assert size == seq.recorder.durable_end_byte > obs.chunks[-1].end_byte
    rec = read_recording(tmp_path / "run.csv")
    assert rec.n_samples == acq.n_samples == seq.recorder.durable_rows
    assert len(rec.sidecar.segments or ()) == len(obs.windows)  # the sidecar kept its last good version
