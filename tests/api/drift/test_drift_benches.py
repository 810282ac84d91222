"""Nightly drift checks in a lab of several benches: each certified unit's check is queued on its
own bench when that bench's agent is live and can run the procedure, once a night however many
API processes run the scheduler; every other unit is listed in ``GET /api/drift`` as not
checked, with the reason."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session, sessionmaker

from api.main import create_app
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Bench, Run, RunState, Unit
from db.process import process_start_ticks
from db.repo.benches import BenchStatus, agent_alive
from db.repo.certificates import issue_certificate
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from station.certificates.statements import NOT_STATED
from station.drift import DriftScheduler, DriftTarget, DueUnit, NotChecked, plan_checks
from station.runs.queue import RunQueue
from tests.support.service_helpers import OP, VIEW, MovableClock, service_settings

HERE = socket.gethostname()


def _dead_pid() -> int:
    """The pid of a process of this host that has ended."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait(timeout=30)
    return child.pid


def _certified(s: Session, serial: str, *, bench: str | None, cert_bench: str | None) -> None:
    """A unit (on ``bench``, or on none) with a completed calibration and its certificate, whose
    content names ``cert_bench`` (``None``: not stated)."""
    bench_id = get_or_create_bench(s, bench).id if bench is not None else None
    unit = get_or_create_unit(s, serial, bench_id=bench_id)
    run = create_run(s, f"cal-{serial}", unit.id, "static-12", bench_id=bench_id, state=RunState.COMPLETED)
    issue_certificate(s, run.id, {"bench": cert_bench if cert_bench is not None else NOT_STATED})


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[tuple[TestClient, MovableClock, sessionmaker[Session]]]:
    """An API (no agent of its own) over a lab of five benches:

    ``bench-a`` agent on another host, fresh, runs static-12; ``bench-b`` agent of this host (this
    test's process), runs both; ``bench-c`` never had an agent; ``bench-d`` agent fresh but its
    table runs rate-1axis only; ``bench-e`` agent of this host whose process has ended (its
    record is fresh).
    """
    clock = MovableClock()
    settings = service_settings(tmp_path, agent="external", drift_time="02:00", bench_name="bench-api")
    with TestClient(create_app(settings, clock=clock, start_scheduler=False)) as client:
        engine = open_database(settings.effective_database_url)
        sessions = make_session_factory(engine)
        try:
            with sessions.begin() as s:
                ids = {name: get_or_create_bench(s, f"bench-{name}").id for name in ("a", "b", "c", "d", "e")}
                me = os.getpid()
                for name, pid, host, procs, start in (
                    ("a", 4242, "host-a", ["static-12"], None),
                    ("b", me, HERE, ["static-12", "rate-1axis"], process_start_ticks(me)),
                    ("d", 4343, "host-d", ["rate-1axis"], None),
                    ("e", _dead_pid(), HERE, ["static-12"], None),
                ):
                    agent_alive(
                        s, ids[name], pid=pid, host=host, procedures=procs, bench_file=None, start_ticks=start
                    )
                _certified(s, "SN-A1", bench="bench-a", cert_bench="bench-a")
                _certified(s, "SN-A2", bench="bench-a", cert_bench="bench-b")  # now mounted on bench-a
                _certified(s, "SN-B1", bench=None, cert_bench="bench-b")  # known from its certificate
                _certified(s, "SN-C1", bench="bench-c", cert_bench="bench-c")
                _certified(s, "SN-D1", bench="bench-d", cert_bench="bench-d")
                _certified(s, "SN-E1", bench="bench-e", cert_bench="bench-e")
                _certified(s, "SN-NOWHERE", bench=None, cert_bench=None)
                get_or_create_unit(s, "SN-NOCERT", bench_id=ids["a"])  # never certified: not due
            yield client, clock, sessions
        finally:
            engine.dispose()


def _drift_runs(sessions: sessionmaker[Session]) -> list[tuple[str, str, str]]:
    """(unit serial, bench name, state) of every drift-check run, by serial."""
    with sessions.begin() as s:
        rows = s.execute(
            sa.select(Unit.serial, Bench.name, Run.state)
            .join(Unit, Run.unit_id == Unit.id)
            .join(Bench, Run.bench_id == Bench.id)
            .where(Run.kind == "drift_check")
            .order_by(Unit.serial, Run.created_at)
        ).all()
    return [(u, b, st.value) for u, b, st in rows]


def _second_api(client: TestClient, clock: MovableClock) -> DriftScheduler:
    """The scheduler of another API process on the same database."""
    services: Any = client.app.state.services  # type: ignore[attr-defined]
    settings, engine = services.settings, services.engine
    sessions = make_session_factory(engine)
    queue = RunQueue(settings, sessions, make_session_factory(engine, read_only=True), clock=clock)
    return DriftScheduler(settings, sessions, queue, clock=clock)


QUEUED = [("SN-A1", "bench-a", "queued"), ("SN-A2", "bench-a", "queued"), ("SN-B1", "bench-b", "queued")]


def test_each_unit_is_checked_on_its_bench_once_a_night_by_two_api_processes(
    lab: tuple[TestClient, MovableClock, sessionmaker[Session]],
) -> None:
    client, clock, sessions = lab
    first: DriftScheduler = client.app.state.services.drift  # type: ignore[attr-defined]
    second = _second_api(client, clock)
    assert first.tick() is None and second.tick() is None  # not yet night
    assert _drift_runs(sessions) == []

    clock.advance(1)  # the night has come for both processes
    night = first.next_run_at
    started = first.tick()
    assert second.tick() == started  # the other process finds this night's checks queued
    assert first.next_run_at != night
    assert _drift_runs(sessions) == QUEUED

    status = client.get("/api/drift", headers=VIEW).json()
    assert status["pending_units"] == ["SN-A1", "SN-A2", "SN-B1"] and status["running"] is False
    reasons = {n["unit_serial"]: (n["bench"], n["reason"]) for n in status["not_checked"]}
    assert reasons == {
        "SN-C1": ("bench-c", "bench 'bench-c' has no live agent (last seen: never)"),
        "SN-D1": ("bench-d", "bench 'bench-d' cannot run static-12; it runs rate-1axis"),
        "SN-E1": ("bench-e", reasons["SN-E1"][1]),
        "SN-NOWHERE": (None, "no bench is known for the unit"),
    }
    assert reasons["SN-E1"][1].startswith("bench 'bench-e' has no live agent (last seen: 20")
    assert {n.unit_serial for n in second.not_checked.values()} == set(reasons)

    # the checks end (here: aborted in the queue); a process whose scheduler fires late that same
    # night queues nothing again, the next night queues them again
    for run in client.get("/api/runs?limit=100", headers=VIEW).json():
        if run["kind"] == "drift_check":
            assert client.post(f"/api/runs/{run['id']}/abort", headers=OP).status_code == 200
    assert second.enqueue(night=night) and _drift_runs(sessions) == [(u, b, "aborted") for u, b, _ in QUEUED]
    clock.advance(1)
    assert first.tick() is not None
    assert [r for r in _drift_runs(sessions) if r[2] == "queued"] == QUEUED


def test_a_check_asked_now_goes_to_the_units_bench_or_says_why_not(
    lab: tuple[TestClient, MovableClock, sessionmaker[Session]],
) -> None:
    client, _, sessions = lab
    r = client.post("/api/drift/run", json={"unit_serial": "SN-B1"}, headers=OP)
    assert r.status_code == 202 and r.json()["pending_units"] == ["SN-B1"], r.text
    r = client.post("/api/drift/run", json={"unit_serial": "SN-D1"}, headers=OP)
    assert r.status_code == 202, r.text
    assert [n["unit_serial"] for n in r.json()["not_checked"]] == ["SN-D1"]
    assert _drift_runs(sessions) == [("SN-B1", "bench-b", "queued")]
    assert client.post("/api/drift/run", json={"unit_serial": "SN-ZZZ"}, headers=OP).status_code == 404


def test_the_plan_names_the_bench_by_its_name_or_bench_file_and_says_why_not() -> None:
    table = {"name": "table-room-2", "version": 1, "sha256": "ef" * 32, "path": "/b.toml"}
    statuses = [
        BenchStatus("bench-x", "busy", None, "h", ("static-12",), table, "R-1", 2),
        BenchStatus("bench-y", "idle", None, "h", (), None, None, 0),  # procedures not told: assumed
    ]
    units = [DueUnit("U1", "table-room-2"), DueUnit("U2", "bench-y"), DueUnit("U3", "bench-gone")]
    targets, skipped = plan_checks(units, statuses, "static-12")
    assert targets == [DriftTarget("U1", "bench-x"), DriftTarget("U2", "bench-y")]  # busy: waits in its queue
    assert skipped == [
        NotChecked("U3", "bench-gone", "bench 'bench-gone' unknown; known benches: bench-x, bench-y")
    ]
