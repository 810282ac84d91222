"""The bench lease: one holder at a time, named to the refused; expiry, a dead holder of this
host, and fencing tokens that only grow (SQLite and PostgreSQL)."""

from __future__ import annotations

import datetime as dt
import os

import pytest
from sqlalchemy.orm import Session, sessionmaker

from db.repo.benches import agent_alive
from db.repo.lease import (
    LeaseHeld,
    LeaseHolder,
    acquire_lease,
    lease_is_current,
    release_lease,
    renew_lease,
)
from db.repo.queue import claim_next_run, queue_run
from db.repo.units import get_or_create_bench, get_or_create_unit

T0 = dt.datetime(2026, 11, 27, 6, 0, tzinfo=dt.UTC)


def holder(pid: int, host: str = "lab-1", kind: str = "calbench agent") -> LeaseHolder:
    return LeaseHolder(pid, host, kind, T0, start_ticks=1000 + pid)


def alive(pid: int, ticks: int | None) -> bool:
    return True


def test_a_held_lease_is_refused_naming_its_holder(db_session_factory: sessionmaker[Session]) -> None:
    with db_session_factory.begin() as s:
        bench = get_or_create_bench(s, "vm").id
        first = acquire_lease(s, bench, holder(11), now=T0, is_alive=alive, host="lab-2")
    with db_session_factory.begin() as s, pytest.raises(LeaseHeld) as err:
        acquire_lease(s, bench, holder(22, "lab-2", "calbench run"), now=T0, is_alive=alive, host="lab-2")
    msg = str(err.value)
    assert "\n" not in msg
    assert "bench 'vm' is driven by calbench agent pid 11 on host lab-1 since 2026-11-27T06:00:00Z" in msg
    # the agent's presence reports do not wipe the lease
    with db_session_factory.begin() as s:
        agent_alive(s, bench, pid=11, host="lab-1", procedures=["static-12"], bench_file=None, now=T0)
        assert lease_is_current(s, bench, first, now=T0 + dt.timedelta(seconds=1))


def test_expiry_and_renewal_and_the_fence(db_session_factory: sessionmaker[Session]) -> None:
    with db_session_factory.begin() as s:
        bench = get_or_create_bench(s, "vm").id
        unit = get_or_create_unit(s, "SN-1").id
        first = acquire_lease(s, bench, holder(11), ttl_s=30, now=T0, is_alive=alive, host="lab-2")
    with db_session_factory.begin() as s:  # renewed at +20 s: still held at +40 s
        assert renew_lease(s, bench, first, ttl_s=30, now=T0 + dt.timedelta(seconds=20))
    with db_session_factory.begin() as s, pytest.raises(LeaseHeld):
        acquire_lease(s, bench, holder(22), now=T0 + dt.timedelta(seconds=40), is_alive=alive, host="lab-2")
    late = T0 + dt.timedelta(seconds=51)  # lapsed: another host's process takes it over
    with db_session_factory.begin() as s:
        second = acquire_lease(s, bench, holder(22, "lab-2"), now=late, is_alive=alive, host="lab-2")
        queue_run(s, "run-1", unit, bench, "static-12", {}, now=late)
    assert second == first + 1
    with db_session_factory.begin() as s:
        # the stalled holder wakes: it cannot renew, and it claims nothing under its old token
        assert not renew_lease(s, bench, first, now=late)
        assert claim_next_run(s, bench, owner_pid=11, owner_host="lab-1", now=late, lease_token=first) is None
        claimed = claim_next_run(s, bench, owner_pid=22, owner_host="lab-2", now=late, lease_token=second)
    assert claimed is not None and claimed.run_id == "run-1"
    with db_session_factory.begin() as s:
        release_lease(s, bench, first)  # a stale release changes nothing
        assert lease_is_current(s, bench, second, now=late)
        release_lease(s, bench, second)
        assert not lease_is_current(s, bench, second, now=late)
        third = acquire_lease(s, bench, holder(33), now=late, is_alive=alive, host="lab-2")
    assert third == second + 1


def test_a_dead_holder_of_this_host_is_replaced_at_once(db_session_factory: sessionmaker[Session]) -> None:
    with db_session_factory.begin() as s:
        bench = get_or_create_bench(s, "vm").id
        acquire_lease(s, bench, holder(11, "here"), now=T0, is_alive=alive, host="here")
    dead_on_this_host: list[tuple[int, int | None]] = []

    def check(pid: int, ticks: int | None) -> bool:
        dead_on_this_host.append((pid, ticks))
        return False

    with db_session_factory.begin() as s:
        token = acquire_lease(s, bench, holder(os.getpid(), "here"), now=T0, is_alive=check, host="here")
    assert token == 2 and dead_on_this_host == [(11, 1011)]
    # a process of another host is not judged by this host's pids
    with db_session_factory.begin() as s, pytest.raises(LeaseHeld):
        acquire_lease(s, bench, holder(44, "elsewhere"), now=T0, is_alive=check, host="elsewhere")
