"""Run-change notifications: delivered to a listener at commit (PostgreSQL), nothing on SQLite.

Notifications on one connection arrive in commit order, so each test ends with a committed
marker and checks the whole list received before it: what must not be notified (a rolled-back
transaction, a heartbeat) is checked without waiting for a timeout.
"""

from __future__ import annotations

import queue
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session, sessionmaker

from db.models import RunState
from db.notify import LISTENER_NAME, RunListener, listen_url, notify_run
from db.repo.progress import record_window
from db.repo.recovery import mark_run_interrupted
from db.repo.runs import finish_run, heartbeat, set_live_progress, set_live_state
from tests.db._factories import make_run

RUN = "20250101T000000Z-SN0001-aaaaaa"
WAIT_S = 20.0
"""Deadline for a notification to arrive (a loaded machine; never a measurement)."""


class Received:
    """The run ids a listener hands over, in order."""

    def __init__(self) -> None:
        self.items: queue.Queue[str] = queue.Queue()
        self.states: list[bool] = []

    def until(self, marker: str) -> list[str]:
        """Every id received up to and including ``marker`` (fails after :data:`WAIT_S`)."""
        got: list[str] = []
        while True:
            item = self.items.get(timeout=WAIT_S)
            got.append(item)
            if item == marker:
                return got


@pytest.fixture
def listened(pg_server: str) -> Iterator[tuple[Received, sessionmaker[Session], Engine]]:
    from db.engine import make_engine, make_session_factory
    from tests.pg import truncate_all

    received = Received()
    conninfo = listen_url(pg_server)
    assert conninfo is not None
    listener = RunListener(conninfo, received.items.put, received.states.append, wait_s=0.2)
    listener.start()
    engine = make_engine(pg_server)
    try:
        assert listener.wait_listening(WAIT_S), "LISTEN never in place"
        yield received, make_session_factory(engine), engine
    finally:
        listener.stop()
        truncate_all(engine)
        engine.dispose()


def _marker(sessions: sessionmaker[Session], name: str) -> None:
    with sessions.begin() as s:
        notify_run(s, name)


def test_listen_url_keeps_the_server_and_drops_the_driver() -> None:
    assert listen_url("postgresql+psycopg://calbench:pw@db:5432/calbench") == (
        "postgresql://calbench:pw@db:5432/calbench"
    )
    assert listen_url("sqlite:////tmp/x.db") is None


@pytest.mark.postgres
def test_a_notification_arrives_at_commit_and_a_rollback_sends_none(
    listened: tuple[Received, sessionmaker[Session], Engine],
) -> None:
    received, sessions, _ = listened
    with sessions() as s:
        s.begin()
        notify_run(s, "R-rolled-back")
        s.rollback()
    _marker(sessions, "R-committed")
    assert received.until("R-committed") == ["R-committed"]
    assert received.states == [True]


@pytest.mark.postgres
def test_writes_the_streams_show_notify_and_a_heartbeat_does_not(
    listened: tuple[Received, sessionmaker[Session], Engine],
) -> None:
    received, sessions, _ = listened
    with sessions.begin() as s:
        make_run(s, RUN)
    _marker(sessions, "M0")
    assert received.until("M0") == ["M0"]  # create_run alone: the agent's on_start notifies

    with sessions.begin() as s:
        heartbeat(s, RUN, progress=0.1)
    _marker(sessions, "M1")
    assert received.until("M1") == ["M1"]

    writes = [
        lambda s: set_live_progress(s, RUN, {"progress": 0.2}),
        lambda s: record_window(s, RUN, 0, start_s=0.0, end_s=1.0, n_samples=100),
        lambda s: set_live_state(s, RUN, RunState.PAUSED),
        lambda s: mark_run_interrupted(s, RUN, "stopped"),
        lambda s: finish_run(s, RUN, RunState.ABORTED, outcome="ABORTED"),
    ]
    for i, write in enumerate(writes):
        with sessions.begin() as s:
            write(s)
        marker = f"W{i}"
        _marker(sessions, marker)
        assert received.until(marker) == [RUN, marker], i

    with sessions.begin() as s:  # a final run: the conditional update changes nothing, no notification
        assert not finish_run(s, RUN, RunState.COMPLETED)
    _marker(sessions, "M2")
    assert received.until("M2") == ["M2"]


@pytest.mark.postgres
def test_a_lost_connection_is_reported_and_listening_resumes(
    listened: tuple[Received, sessionmaker[Session], Engine],
) -> None:
    received, sessions, engine = listened
    with engine.connect() as conn:  # end the listener's backend, as a server restart would
        ended = conn.execute(
            sa.text(
                "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity "
                "WHERE application_name = :name AND datname = current_database()"
            ),
            {"name": LISTENER_NAME},
        ).scalar_one()
    assert ended == 1
    deadline = time.monotonic() + WAIT_S
    while received.states[-2:] != [False, True] and time.monotonic() < deadline:
        time.sleep(0.05)
    assert received.states == [True, False, True]
    _marker(sessions, "after")
    assert received.until("after") == ["after"]


def test_notify_run_sends_nothing_on_sqlite(tmp_path: Path) -> None:
    from db.engine import make_engine, make_session_factory
    from db.migrate import upgrade

    engine = make_engine(f"sqlite:///{tmp_path / 'n.db'}")
    upgrade(engine)
    statements: list[str] = []
    sa.event.listen(engine, "before_cursor_execute", lambda *a: statements.append(str(a[2])))
    try:
        with make_session_factory(engine).begin() as s:
            notify_run(s, RUN)
        assert not [q for q in statements if "notify" in q.lower()]
    finally:
        engine.dispose()
