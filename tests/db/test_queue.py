"""The run queue on SQLite and PostgreSQL: claims are exclusive (also under concurrent
claimers with their own connections), in order, one run per bench at a time; control
requests reach the owner; a queued run is waiting, not dead; a resume is queued like a run."""

from __future__ import annotations

import datetime as dt
import threading

import pytest
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session, sessionmaker

from db.engine import make_engine, make_session_factory
from db.models import Run, RunState, SampleChunk
from db.repo.progress import record_chunk, record_window
from db.repo.queue import (
    claim_next_run,
    pending_control,
    queue_resume,
    queue_run,
    queued_runs,
    request_control,
)
from db.repo.recovery import mark_interrupted_runs
from db.repo.runs import finish_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from db.types import utc_now


def _queue(s: Session, run_id: str, bench: str = "bench-a", serial: str = "SN-Q") -> int:
    b = get_or_create_bench(s, bench)
    u = get_or_create_unit(s, serial, bench_id=b.id)
    queue_run(s, run_id, u.id, b.id, "static-12", {}, kind="calibration", requested_dwell_s=3.0)
    return b.id


def test_claims_in_order_one_run_per_bench(db_session_factory: sessionmaker[Session]) -> None:
    with db_session_factory.begin() as s:
        bench_a = _queue(s, "r1")
        _queue(s, "r2")
        bench_b = _queue(s, "b1", bench="bench-b")
    with db_session_factory.begin() as s:
        assert [r.id for r in queued_runs(s, bench_a)] == ["r1", "r2"]
        first = claim_next_run(s, bench_a, owner_pid=11, owner_host="h")
        assert first is not None and first.run_id == "r1" and first.point is None
        assert first.requested_dwell_s == 3.0 and first.kind == "calibration" and first.unit_serial == "SN-Q"
    with db_session_factory.begin() as s:
        # bench-a holds r1: nothing more for it; bench-b is another table
        assert claim_next_run(s, bench_a, owner_pid=12, owner_host="h") is None
        other = claim_next_run(s, bench_b, owner_pid=13, owner_host="h")
        assert other is not None and other.run_id == "b1"
        run = s.get(Run, "r1")
        assert (
            run is not None and run.state is RunState.RUNNING and (run.owner_pid, run.owner_host) == (11, "h")
        )
    with db_session_factory.begin() as s:
        finish_run(s, "r1", RunState.COMPLETED)
        second = claim_next_run(s, bench_a, owner_pid=12, owner_host="h")
        assert second is not None and second.run_id == "r2"
        assert claim_next_run(s, bench_a, owner_pid=12, owner_host="h") is None


def test_concurrent_claimers_get_each_run_once(db_engine: Engine) -> None:
    """Eight claimers, each with its own engine (connections), race for three queued runs of
    one bench and three of another: each run is claimed exactly once, and never two runs of
    one bench at the same time."""
    factory = make_session_factory(db_engine)
    with factory.begin() as s:
        ids = {"bench-a": ["a1", "a2", "a3"], "bench-b": ["b1", "b2", "b3"]}
        bench_ids = {name: _queue(s, rid, bench=name) for name, runs in ids.items() for rid in runs}
    claims: list[tuple[str, str, int]] = []
    errors: list[BaseException] = []
    lock = threading.Lock()
    url = db_engine.url

    def claimer(pid: int) -> None:
        engine = make_engine(url)
        own = make_session_factory(engine)
        try:
            for _ in range(30):
                for name, bench_id in bench_ids.items():
                    with own.begin() as s:
                        got = claim_next_run(s, bench_id, owner_pid=pid, owner_host="h")
                        if got is None:
                            continue
                        with lock:
                            claims.append((name, got.run_id, pid))
                        holding = s.query(Run).filter(Run.bench_id == bench_id, Run.state == RunState.RUNNING)
                        assert holding.count() == 1, f"two runs of {name} running at once"
                    with own.begin() as s:  # the run ends; the bench is free again
                        finish_run(s, got.run_id, RunState.COMPLETED)
        except BaseException as exc:
            errors.append(exc)
        finally:
            engine.dispose()

    threads = [threading.Thread(target=claimer, args=(100 + i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not errors, errors
    claimed = sorted(rid for _, rid, _ in claims)
    assert claimed == sorted(ids["bench-a"] + ids["bench-b"])  # each exactly once
    for name in ids:  # in queue order per bench
        assert [rid for n, rid, _ in claims if n == name] == ids[name]


def test_control_requests_and_queued_abort(db_session_factory: sessionmaker[Session]) -> None:
    with db_session_factory.begin() as s:
        bench = _queue(s, "r1")
        _queue(s, "r2")
        claim_next_run(s, bench, owner_pid=11, owner_host="h")
    with db_session_factory.begin() as s:
        assert request_control(s, "r1", "pause") is RunState.RUNNING
        assert request_control(s, "r1", "continue") is RunState.RUNNING
        assert request_control(s, "r2", "pause") is RunState.QUEUED  # held once it starts
        assert request_control(s, "r2", "abort", "not needed") is RunState.ABORTED
    with db_session_factory.begin() as s:
        assert pending_control(s, "r1").seq == 2 and pending_control(s, "r1").action == "continue"
        assert pending_control(s, "r1").abort is None
        assert request_control(s, "r1", "abort", "stop now") is RunState.RUNNING
        assert pending_control(s, "r1").abort == "stop now"
        r2 = s.get(Run, "r2")
        assert r2 is not None and r2.error == "aborted before it started: not needed" and r2.owner_pid is None
        with pytest.raises(LookupError):
            request_control(s, "nope", "abort")
        finish_run(s, "r1", RunState.ABORTED)
        assert request_control(s, "r1", "abort") is None  # final: the route answers 409


def test_a_queued_run_waits_however_long(db_session_factory: sessionmaker[Session]) -> None:
    with db_session_factory.begin() as s:
        _queue(s, "r1")
    later = utc_now() + dt.timedelta(days=1)
    with db_session_factory.begin() as s:
        assert mark_interrupted_runs(s, "h", lambda pid: False, now=later) == []
        run = s.get(Run, "r1")
        assert run is not None and run.state is RunState.QUEUED


def test_resume_is_queued_and_claimed_at_its_window(db_session_factory: sessionmaker[Session]) -> None:
    with db_session_factory.begin() as s:
        bench = _queue(s, "r1")
        claim_next_run(s, bench, owner_pid=11, owner_host="h")
        for seq in range(3):
            record_chunk(
                s,
                "r1",
                seq,
                first_sample=100 * seq,
                n_samples=100,
                last_t_s=1.0 * (seq + 1),
                end_byte=1000 * (seq + 1),
                window_index=0,
            )
        record_window(s, "r1", 0, start_s=0.2, end_s=1.5, n_samples=130)
    with db_session_factory.begin() as s:
        assert queue_resume(s, "r1") is None  # running: not interrupted
        assert mark_interrupted_runs(s, "h", lambda pid: False) == ["r1"]
    with db_session_factory.begin() as s:
        point = queue_resume(s, "r1")
        assert point is not None and point.next_window_index == 1 and point.keep_chunks == 2
        run = s.get(Run, "r1")
        assert run is not None and run.state is RunState.QUEUED and run.owner_pid is None
    with db_session_factory.begin() as s:
        claimed = claim_next_run(s, bench, owner_pid=12, owner_host="h")
        assert claimed is not None and claimed.point is not None
        assert claimed.point.keep_end_byte == 2000 and claimed.point.next_window_index == 1
        run = s.get(Run, "r1")
        assert run is not None and run.resume_count == 1 and not run.resume_requested
        kept = s.query(SampleChunk.seq).filter(SampleChunk.run_id == "r1").order_by(SampleChunk.seq).all()
        assert [k for (k,) in kept] == [0, 1]  # the chunk after the last complete window is gone
