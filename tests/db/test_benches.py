"""Benches as the API sees them: agents' presence, state, queue, and which bench a run goes to."""

from __future__ import annotations

import datetime as dt

import pytest
from sqlalchemy.orm import Session, sessionmaker

from db.models import RunState
from db.repo.benches import (
    AGENT_STALE_S,
    BenchStatus,
    agent_alive,
    agent_gone,
    bench_status,
    choose_bench,
    find_bench,
)
from db.repo.queue import queue_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from tests.db._factories import make_run

T0 = dt.datetime(2026, 1, 1, 12, 0, tzinfo=dt.UTC)
FILE_A = {"name": "table-room-1", "version": 2, "sha256": "ab" * 32, "path": "/etc/calbench/a.toml"}


def _status(
    name: str,
    state: str = "idle",
    *,
    queued: int = 0,
    holding: str | None = None,
    procs: tuple[str, ...] = ("static-12",),
) -> BenchStatus:
    return BenchStatus(name, state, T0, "h", procs, None, holding, queued)  # type: ignore[arg-type]


def test_states_from_the_agents_reports_and_the_runs(db_session_factory: sessionmaker[Session]) -> None:
    with db_session_factory.begin() as s:
        a = get_or_create_bench(s, "bench-a").id
        b = get_or_create_bench(s, "bench-b").id
        get_or_create_bench(s, "bench-c")  # never reported: offline
        agent_alive(
            s, a, pid=11, host="h1", procedures=["static-12", "rate-1axis"], bench_file=FILE_A, now=T0
        )
        agent_alive(s, b, pid=12, host="h2", procedures=["static-12"], bench_file=None, now=T0)
        make_run(s, "R-hold", "SN-1", state=RunState.RUNNING, bench_name="bench-b")
        unit = get_or_create_unit(s, "SN-2")
        queue_run(s, "R-q1", unit.id, b, "static-12", {})
        queue_run(s, "R-q2", unit.id, b, "static-12", {})
    fresh = T0 + dt.timedelta(seconds=AGENT_STALE_S - 1)
    with db_session_factory.begin() as s:
        got = {st.name: st for st in bench_status(s, now=fresh)}
    assert (got["bench-a"].state, got["bench-a"].holding_run, got["bench-a"].n_queued) == ("idle", None, 0)
    assert got["bench-a"].procedures == ("static-12", "rate-1axis")
    assert got["bench-a"].bench_file == FILE_A and got["bench-a"].agent_host == "h1"
    assert (got["bench-b"].state, got["bench-b"].holding_run, got["bench-b"].n_queued) == (
        "busy",
        "R-hold",
        2,
    )
    assert got["bench-c"].state == "offline" and got["bench-c"].procedures == ()

    stale = T0 + dt.timedelta(seconds=AGENT_STALE_S + 1)
    with db_session_factory.begin() as s:
        assert {st.name: st.state for st in bench_status(s, now=stale)} == {
            "bench-a": "offline",
            "bench-b": "offline",
            "bench-c": "offline",
        }
    with db_session_factory.begin() as s:  # a stop of another process leaves the record; its own clears it
        agent_gone(s, a, pid=99, host="h1")
        agent_gone(s, b, pid=12, host="h2")
    with db_session_factory.begin() as s:
        states = {st.name: st.state for st in bench_status(s, now=fresh)}
    assert states == {"bench-a": "idle", "bench-b": "offline", "bench-c": "offline"}


def test_a_bench_is_found_by_its_name_or_its_bench_files_name() -> None:
    a = BenchStatus("bench-a", "idle", T0, "h", (), FILE_A, None, 0)
    b = BenchStatus("bench-b", "idle", T0, "h", (), None, None, 0)
    assert find_bench([a, b], "bench-b") is b
    assert find_bench([a, b], "table-room-1") is a
    with pytest.raises(LookupError, match=r"bench 'bench-z' unknown; known benches: bench-a, bench-b"):
        find_bench([a, b], "bench-z")
    twin = BenchStatus("bench-c", "idle", T0, "h", (), FILE_A, None, 0)
    with pytest.raises(LookupError, match=r"several benches \(bench-a, bench-c\)"):
        find_bench([a, twin], "table-room-1")


def test_a_run_left_to_the_service_goes_to_a_free_bench_that_can_run_it() -> None:
    busy_own = _status("own", "busy", holding="R1")
    free = _status("zeta")
    assert choose_bench([busy_own, free], "static-12", prefer="own") == "zeta"
    # all busy: the shortest queue, ties to the service's own bench, then by name
    assert choose_bench([busy_own, _status("b", "busy", holding="R2", queued=1)], "static-12", "own") == "own"
    assert (
        choose_bench(
            [_status("b", "busy", holding="R2"), _status("a", "busy", holding="R3")], "static-12", "own"
        )
        == "a"
    )
    # offline benches and benches that cannot run it are never chosen
    assert choose_bench([_status("a", "offline"), busy_own], "static-12", "own") == "own"
    no_rate = _status("a", procs=("static-12",))
    assert (
        choose_bench([no_rate, _status("b", "busy", holding="R", procs=("rate-1axis",))], "rate-1axis", "a")
        == "b"
    )
    assert choose_bench([no_rate, _status("c", "offline")], "rate-1axis", "a") is None


def test_an_agent_of_this_host_whose_process_is_gone_is_offline_at_once(
    db_session_factory: sessionmaker[Session],
) -> None:
    """Same host: the pid and the process start time decide at once; another host: staleness only."""
    gone: set[int] = {21}  # pids of this host with no process
    started = {22: 1000}  # pid 22 runs, started at tick 1000

    def is_alive(pid: int, start: int | None) -> bool:
        return pid not in gone and (start is None or started.get(pid) == start)

    with db_session_factory.begin() as s:
        for name, pid, host, start in (
            ("dead-here", 21, "here", 500),
            ("live-here", 22, "here", 1000),
            ("reused-pid", 22, "here", 999),  # pid 22 is now another process
            ("unknown-start", 22, "here", None),
            ("dead-elsewhere", 21, "there", 500),
        ):
            bench_id = get_or_create_bench(s, name).id
            agent_alive(
                s, bench_id, pid=pid, host=host, procedures=[], bench_file=None, start_ticks=start, now=T0
            )
    fresh = T0 + dt.timedelta(seconds=1)
    with db_session_factory.begin() as s:
        states = {st.name: st.state for st in bench_status(s, now=fresh, host="here", is_alive=is_alive)}
    assert states == {
        "dead-elsewhere": "idle",  # another host's pid says nothing here: fresh record, online
        "dead-here": "offline",
        "live-here": "idle",
        "reused-pid": "offline",
        "unknown-start": "idle",
    }
    stale = T0 + dt.timedelta(seconds=AGENT_STALE_S + 1)
    with db_session_factory.begin() as s:
        states = {st.name: st.state for st in bench_status(s, now=stale, host="here", is_alive=is_alive)}
    assert set(states.values()) == {"offline"}
