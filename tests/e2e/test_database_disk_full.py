"""A real full disk holding both the SQLite database and the recordings (a tmpfs of a few MB,
filled mid-run): the run is left ``interrupted`` as a device fault — not ERROR — whether SQLite
or the recording meets the full disk first; once the disk is cleared (while the run's end is
retried) it resumes and completes (a resume tried while the disk is still full is a failed
try, the run left as it was), and the database and the recording agree on every window,
chunk, row and byte. Needs root to mount the tmpfs; skipped otherwise."""

from __future__ import annotations

import ctypes
import errno
import os
import sqlite3
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from bench.recording.reader import read_recording
from bench.records import RunStart, WindowRecord
from bench.run_observer import NullObserver
from bench.run_state import RunState
from station.execution import verdict
from station.execution.continuation import resume_run
from station.execution.fault_retry import FAULT_PREFIX, ResumeFailed
from station.execution.session import start_run
from tests.e2e.helpers import SIM_SPEED, settings_for

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]

FALLOC_FL_KEEP_SIZE = 1


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A tmpfs of 16 MB mounted in ``tmp_path``: a file system that really fills."""
    if os.geteuid() != 0:
        pytest.skip("mounting a size-limited tmpfs needs root")
    mnt = tmp_path / "disk"
    mnt.mkdir()
    r = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=16m,mode=0700", "tmpfs", str(mnt)],
        capture_output=True,
        text=True,
    )
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


class FillDisk(NullObserver):
    """After window ``at`` is stored, fills the disk to its last byte. SQLite's write-ahead log
    is first truncated (a checkpoint, as SQLite does itself), so its next write needs new
    space. ``room_for_recording``: the recording's file first gets space reserved beyond its end
    (``fallocate`` keeping its size), so the database is what meets the full disk first."""

    def __init__(self, disk: Path, at: int, room_for_recording: bool) -> None:
        self.disk, self.at, self.room = disk, at, room_for_recording
        self.filler = disk / "filler.bin"
        self.csv: Path | None = None
        self.filled = 0

    def on_start(self, start: RunStart) -> None:
        self.csv = Path(start.recording_path)

    def on_window(self, run_id: str, window: WindowRecord) -> None:
        if window.index == self.at and not self.filled:
            self.fill(self.room)

    def fill(self, room_for_recording: bool) -> None:
        """Truncate the write-ahead log, reserve room for the recording if asked, fill the rest."""
        with sqlite3.connect(self.disk / "calbench.db") as conn:
            busy, _, _ = conn.execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchone()
        assert busy == 0 and (self.disk / "calbench.db-wal").stat().st_size == 0
        if room_for_recording:
            assert self.csv is not None
            fd = os.open(self.csv, os.O_WRONLY)
            try:
                libc = ctypes.CDLL(None, use_errno=True)
                size = os.fstat(fd).st_size
                rc = libc.fallocate(fd, FALLOC_FL_KEEP_SIZE, ctypes.c_int64(size), ctypes.c_int64(4 << 20))
                assert rc == 0, os.strerror(ctypes.get_errno())
            finally:
                os.close(fd)
        fd = os.open(self.filler, os.O_WRONLY | os.O_CREAT, 0o600)
        try:
            block = 1 << 20
            while block:
                try:
                    self.filled += os.write(fd, b"\0" * block)
                except OSError as exc:
                    assert exc.errno == errno.ENOSPC
                    block //= 2
        finally:
            os.close(fd)


def durable(db: Path) -> tuple[str, int | None, int, int]:
    with sqlite3.connect(db) as conn:
        state, last = conn.execute("SELECT state, last_complete_window FROM run").fetchone()
        rows, end = conn.execute(
            "SELECT max(first_sample + n_samples), max(end_byte) FROM sample_chunk"
        ).fetchone()
    return state, last, int(rows), int(end)


@pytest.mark.parametrize("first", ["database", "recording"])
def test_a_full_disk_under_the_database_and_the_recording_interrupts_and_resumes(
    small_disk: Path, first: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    settings = settings_for(small_disk)
    fill = FillDisk(small_disk, at=3, room_for_recording=first == "database")
    cleared: list[int] = []

    def clearing_sleep(s: float) -> None:  # the operator clears the disk while the end is retried
        if fill.filler.exists():
            fill.filler.unlink()
            cleared.append(1)
        time.sleep(s)

    monkeypatch.setattr(verdict, "time", SimpleNamespace(monotonic=time.monotonic, sleep=clearing_sleep))
    record = start_run(
        settings, "static-12", "SN-FULL", sim=True, sim_speed=SIM_SPEED, seed=3, dwell_s=2.0, observers=[fill]
    )
    assert fill.filled > 0 and cleared == [1]  # the disk was full, and the run's end waited for room
    assert record.state is RunState.INTERRUPTED, record.error
    error = record.error or ""
    assert error.startswith(FAULT_PREFIX), error
    if first == "database":
        assert "DbRunObserver" in error and "database or disk is full" in error, error
    else:
        assert "No space left on device" in error, error
    db = small_disk / "calbench.db"
    state, last, rows, end = durable(db)
    assert state == "interrupted" and last is not None and last >= 3
    csv = Path(str(record.start.recording_path))
    assert csv.stat().st_size >= end  # nothing the database holds is missing from the file

    monkeypatch.undo()
    # a resume tried while the disk is still full is a failed try (calbench run tries again
    # after its wait), the run left interrupted, not a crash
    fill.fill(room_for_recording=False)
    with pytest.raises(ResumeFailed, match="the database refused its claim: the disk is full"):
        resume_run(settings, record.run_id, sim=True, sim_speed=SIM_SPEED)
    assert durable(db)[:2] == (state, last)
    fill.filler.unlink()
    resumed = resume_run(settings, record.run_id, sim=True, sim_speed=SIM_SPEED)
    assert resumed.state is RunState.COMPLETED, resumed.error
    state, last, rows, end = durable(db)
    assert (state, last) == ("completed", 11)
    rec = read_recording(csv)
    assert [s.label for s in rec.sidecar.segments or ()] == [f"pos{i:02d}" for i in range(1, 13)]
    assert rec.n_samples == rows == resumed.n_samples and csv.stat().st_size == end
    assert np.all(np.diff(rec.t_s) > 0)
