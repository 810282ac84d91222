"""Interrupted runs: dead owners found on restart; resume point and single claim."""

from __future__ import annotations

import datetime as dt
import os
import subprocess
import sys

import pytest
import sqlalchemy as sa

from db.models import Run, RunState, SampleChunk
from db.repo import progress, recovery
from tests.db._factories import make_run

NOW = dt.datetime(2025, 6, 1, 12, 0, tzinfo=dt.UTC)


def _dead_pid() -> int:
    proc = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, check=True
    )
    return int(proc.stdout)


def test_process_alive_on_this_host():
    assert recovery.process_alive(os.getpid())
    assert not recovery.process_alive(_dead_pid())
    assert not recovery.process_alive(0)


def test_dead_owner_on_this_host_marked_interrupted(db_session_factory):
    dead = _dead_pid()
    with db_session_factory.begin() as s:
        make_run(s, "R-dead", state=RunState.RUNNING, owner_pid=dead, owner_host="here")
        make_run(s, "R-alive", state=RunState.RUNNING, owner_pid=os.getpid(), owner_host="here")
        make_run(s, "R-paused", state=RunState.PAUSED, owner_pid=dead, owner_host="here")
        make_run(s, "R-done", state=RunState.COMPLETED, owner_pid=dead, owner_host="here")
    with db_session_factory.begin() as s:
        marked = recovery.mark_interrupted_runs(s, "here")
    assert sorted(marked) == ["R-dead", "R-paused"]
    with db_session_factory() as s:
        states = dict(s.execute(sa.select(Run.id, Run.state)).all())
        assert states == {
            "R-dead": RunState.INTERRUPTED,
            "R-paused": RunState.INTERRUPTED,
            "R-alive": RunState.RUNNING,
            "R-done": RunState.COMPLETED,
        }
        assert f"owner process {dead} on here is gone" in s.get(Run, "R-dead").error


def test_other_host_judged_by_heartbeat_age_only(db_session_factory):
    with db_session_factory.begin() as s:
        fresh = make_run(s, "R-fresh", owner_pid=1, owner_host="bench-b")
        stale = make_run(s, "R-stale", owner_pid=1, owner_host="bench-b")
        fresh.heartbeat_at = NOW - dt.timedelta(seconds=30)
        stale.heartbeat_at = NOW - dt.timedelta(seconds=301)
    with db_session_factory.begin() as s:
        # is_alive must not be asked about another host's pids
        marked = recovery.mark_interrupted_runs(s, "bench-a", lambda pid: pytest.fail("asked"), now=NOW)
    assert marked == ["R-stale"]
    with db_session_factory.begin() as s:
        assert recovery.mark_interrupted_runs(s, "bench-a", now=NOW + dt.timedelta(seconds=271)) == [
            "R-fresh"
        ]


def test_marking_twice_marks_once(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1", owner_pid=5, owner_host="h")
    with db_session_factory.begin() as s:
        assert recovery.mark_interrupted_runs(s, "h", lambda pid: False) == ["R-1"]
    with db_session_factory.begin() as s:
        assert recovery.mark_interrupted_runs(s, "h", lambda pid: False) == []


def _record(s, run_id, windows, chunks):
    for i, (a, b) in enumerate(windows):
        progress.record_window(s, run_id, i, start_s=a, end_s=b, n_samples=int((b - a) * 100))
    for seq, (first, n, last_t, end_byte) in enumerate(chunks):
        progress.record_chunk(
            s, run_id, seq, first_sample=first, n_samples=n, last_t_s=last_t, end_byte=end_byte
        )


def test_resume_point_cuts_after_the_chunk_that_completes_the_last_window(db_session_factory):
    # 100 Hz; windows 0: 5-15 s, 1: 25-35 s; window 2 was in progress (45-...) when the process died.
    chunks = [
        (0, 1000, 9.99, 10_000),
        (1000, 1000, 19.99, 20_000),
        (2000, 1000, 29.99, 30_000),
        (3000, 1000, 39.99, 40_000),
        (4000, 1000, 49.99, 50_000),
    ]
    with db_session_factory.begin() as s:
        make_run(s, "R-1", owner_pid=5, owner_host="h")
        _record(s, "R-1", [(5.0, 15.0), (25.0, 35.0)], chunks)
        recovery.mark_interrupted_runs(s, "h", lambda pid: False)
    with db_session_factory() as s:
        point = recovery.resume_point(s, "R-1")
    # window 1 ends at 35 s; the first chunk reaching 35 s is seq 3 (last sample 39.99 s)
    assert point == recovery.ResumePoint("R-1", "/data/R-1.csv", 2, 35.0, 4, 4000, 40_000)


def test_resume_point_without_a_complete_window_starts_over(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        _record(s, "R-1", [], [(0, 500, 4.99, 5000)])
    with db_session_factory() as s:
        point = recovery.resume_point(s, "R-1")
    assert (point.next_window_index, point.keep_chunks, point.keep_samples, point.keep_end_byte) == (
        0,
        0,
        0,
        None,
    )


def test_resume_point_refuses_a_window_the_chunks_do_not_hold(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        _record(s, "R-1", [(5.0, 15.0)], [(0, 1000, 9.99, 10_000)])
    with db_session_factory() as s, pytest.raises(ValueError, match=r"window 0 ends at 15\.0 s"):
        recovery.resume_point(s, "R-1")


def test_claim_for_resume_once_and_drops_chunks_past_the_cut(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1", owner_pid=5, owner_host="h")
        _record(s, "R-1", [(0.0, 5.0)], [(0, 600, 5.99, 6000), (600, 600, 11.99, 12_000)])
        recovery.mark_interrupted_runs(s, "h", lambda pid: False)
    with db_session_factory.begin() as s:
        point = recovery.claim_for_resume(s, "R-1", owner_pid=77, owner_host="h2", now=NOW)
    assert (point.next_window_index, point.keep_chunks, point.keep_end_byte) == (1, 1, 6000)
    with db_session_factory() as s:
        run = s.get(Run, "R-1")
        assert (run.state, run.owner_pid, run.owner_host, run.resume_count, run.error) == (
            RunState.RUNNING,
            77,
            "h2",
            1,
            None,
        )
        assert s.scalars(sa.select(SampleChunk.seq)).all() == [0]
    with pytest.raises(ValueError, match="run R-1 is running"), db_session_factory.begin() as s:
        recovery.claim_for_resume(s, "R-1", owner_pid=78, owner_host="h3")
    with pytest.raises(LookupError), db_session_factory.begin() as s:
        recovery.claim_for_resume(s, "R-404", owner_pid=78, owner_host="h3")
