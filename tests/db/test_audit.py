"""The audit trail written by the run's own transitions: a start from the command line, the
agent's state changes, a crash found at the next start, a resume, the end."""

from __future__ import annotations

import datetime as dt
import getpass
import subprocess
import sys

import pytest
from sqlalchemy.orm import Session, sessionmaker

from db.models import AGENT, SYSTEM, AuditAction, RunState
from db.repo import progress, recovery, runs
from db.repo.audit import command_line_actor, record_action, run_audit
from tests.db._factories import make_run

NOW = dt.datetime(2025, 6, 1, 12, 0, tzinfo=dt.UTC)


def _dead_pid() -> int:
    proc = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, check=True
    )
    return int(proc.stdout)


def _rows(s: Session, run_id: str) -> list[tuple[str, str, str | None, str, int | None]]:
    return [
        (a.action.value, a.actor, a.state.value if a.state else None, a.detail, a.window_index)
        for a in run_audit(s, run_id)
    ]


def test_a_run_course_is_written_as_it_goes(db_session_factory: sessionmaker[Session]) -> None:
    dead = _dead_pid()
    with db_session_factory.begin() as s:
        make_run(s, "R1", owner_pid=dead, owner_host="here")
        runs.set_live_state(s, "R1", RunState.RUNNING, reason="started", now=NOW)
        for i in range(3):
            progress.record_window(s, "R1", i, start_s=i, end_s=i + 0.5, n_samples=50)
            progress.record_chunk(
                s, "R1", i, first_sample=100 * i, n_samples=100, last_t_s=i + 0.9, end_byte=1000 * (i + 1)
            )
        runs.set_live_state(s, "R1", RunState.SUSPENDED, reason="interlock open", now=NOW)
    with db_session_factory.begin() as s:  # the owner died: the next start marks it
        assert recovery.mark_interrupted_runs(s, "here", now=NOW) == ["R1"]
    with db_session_factory.begin() as s:
        recovery.claim_for_resume(s, "R1", owner_pid=7, owner_host="here", actor="Ada Lovelace", now=NOW)
        runs.finish_run(s, "R1", RunState.COMPLETED, outcome="PASS", now=NOW)
    with db_session_factory.begin() as s:
        got = _rows(s, "R1")
        times = [a.at for a in run_audit(s, "R1")]
    assert got == [
        ("start", command_line_actor(), None, "static-12", None),
        ("state", AGENT, "running", "started", 0),
        ("state", AGENT, "suspended", "interlock open", 3),
        ("state", SYSTEM, "interrupted", f"owner process {dead} on here is gone", 3),
        ("resume", "Ada Lovelace", None, "from window 3", 3),
        ("state", AGENT, "completed", "outcome PASS", None),
    ]
    assert getpass.getuser() in got[0][1]
    assert all(t.tzinfo is not None and t.utcoffset() == dt.timedelta(0) for t in times)


def test_an_action_names_who_took_it(db_session_factory: sessionmaker[Session]) -> None:
    with db_session_factory.begin() as s:
        make_run(s, "R2")
        with pytest.raises(ValueError, match="needs an actor"):
            record_action(s, "R2", AuditAction.PAUSE, "  ")
        with pytest.raises(ValueError, match="state row carries the new state"):
            record_action(s, "R2", AuditAction.STATE, AGENT)


def test_the_trail_goes_with_the_run(db_session_factory: sessionmaker[Session]) -> None:
    from db.models import Run

    with db_session_factory.begin() as s:
        make_run(s, "R3", state=RunState.COMPLETED)
    with db_session_factory.begin() as s:
        assert len(run_audit(s, "R3")) == 1
        s.delete(s.get(Run, "R3"))
    with db_session_factory.begin() as s:
        assert run_audit(s, "R3") == []
