"""The run queue of the benches: API processes queue runs and control requests, each bench's
agent claims the next run of its bench and follows the requests.

A queued run is a ``run`` row in state ``queued`` with no owner (``owner_pid`` NULL). The
agent of its bench claims it with :func:`claim_next_run`: in one transaction it locks the
bench row (``SELECT … FOR UPDATE`` on PostgreSQL; on SQLite every writing transaction begins
``IMMEDIATE`` and is alone anyway), checks that no other run of the bench is live, picks the
oldest queued run with ``SELECT … FOR UPDATE SKIP LOCKED`` (PostgreSQL) and moves it to
``running`` with a conditional ``UPDATE … WHERE state = 'queued'``: of two agents (or two
claims) exactly one gets it, and a bench never runs two runs at once.

Control requests (abort, pause, continue) are written into the run's ``params`` by
:func:`request_control`; the agent reads them with :func:`pending_control`. An abort is
sticky (``params["abort_requested"]``); pause and continue are a numbered request
(``params["control"] = {"seq", "action"}``): the agent applies the newest one it has not
applied, from the claim on, so a pause asked of a run still waiting in the queue holds it as
soon as it starts. A resume of an ``interrupted`` run is queued like a fresh run
(:func:`queue_resume`, ``params["resume_requested"]``); the claim then computes where the
recording is cut and deletes the chunk rows after it, as :func:`db.repo.recovery.claim_for_resume`.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from typing import Any, Literal

import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import Bench, Run, RunState, SampleChunk, Unit
from db.notify import notify_run
from db.repo.lease import lease_is_current
from db.repo.recovery import ResumePoint, resume_point
from db.types import utc_now

ControlAction = Literal["abort", "pause", "continue"]
HOLDING_STATES = (RunState.RUNNING, RunState.PAUSED, RunState.SUSPENDED)
"""States of a run that holds its bench (an owner process drives the table)."""
RESUME_KEY = "resume_requested"
ABORT_KEY = "abort_requested"
CONTROL_KEY = "control"
FINISHING_KEY = "finishing_since"
"""``params`` key set by the owner when every step is done (:func:`enter_finishing`): from then
on abort, pause and continue are refused."""


@dataclasses.dataclass(frozen=True)
class ClaimedRun:
    """A run an agent has just claimed.

    :param params: the run's parameters as queued (request, kind, …).
    :param point: where a resumed run picks up; ``None`` for a fresh run.
    """

    run_id: str
    unit_serial: str
    model: str | None
    procedure: str
    params: dict[str, Any]
    point: ResumePoint | None


def _dialect(session: Session) -> str:
    return session.get_bind().dialect.name


def queue_run(
    session: Session,
    run_id: str,
    unit_id: int,
    bench_id: int,
    procedure: str,
    params: dict[str, Any],
    *,
    now: dt.datetime | None = None,
) -> Run:
    """Add a run ``queued`` for the bench, with no owner (an agent claims it)."""
    now = now or utc_now()
    run = Run(
        id=run_id,
        unit_id=unit_id,
        bench_id=bench_id,
        procedure=procedure,
        state=RunState.QUEUED,
        progress=0.0,
        params=dict(params),
        created_at=now,
        heartbeat_at=now,
    )
    session.add(run)
    session.flush()
    return run


def holding_run(session: Session, bench_id: int) -> Run | None:
    """The run that holds the bench (running, paused or suspended), if any."""
    return session.scalars(
        sa.select(Run).where(Run.bench_id == bench_id, Run.state.in_(HOLDING_STATES)).limit(1)
    ).one_or_none()


def queued_runs(session: Session, bench_id: int) -> list[Run]:
    """The bench's queued runs, oldest first (the order the agent claims them)."""
    return list(
        session.scalars(
            sa.select(Run)
            .where(Run.bench_id == bench_id, Run.state == RunState.QUEUED, Run.owner_pid.is_(None))
            .order_by(Run.created_at, Run.id)
        )
    )


def claim_next_run(
    session: Session,
    bench_id: int,
    *,
    owner_pid: int,
    owner_host: str,
    now: dt.datetime | None = None,
    lease_token: int | None = None,
) -> ClaimedRun | None:
    """Claim the bench's oldest queued run for ``owner_pid@owner_host``; ``None`` when the
    bench holds a run already, nothing is queued, or ``lease_token`` (the claimer's fencing
    token, :mod:`db.repo.lease`) is no longer the bench's.

    :raises LookupError: no bench ``bench_id``.
    """
    now = now or utc_now()
    locked = session.scalar(sa.select(Bench.id).where(Bench.id == bench_id).with_for_update())
    if locked is None:
        raise LookupError(f"bench {bench_id} not found")
    if lease_token is not None and not lease_is_current(session, bench_id, lease_token, now=now):
        return None
    if holding_run(session, bench_id) is not None:
        return None
    stmt = (
        sa.select(Run.id)
        .where(Run.bench_id == bench_id, Run.state == RunState.QUEUED, Run.owner_pid.is_(None))
        .order_by(Run.created_at, Run.id)
        .limit(1)
    )
    if _dialect(session) == "postgresql":
        stmt = stmt.with_for_update(skip_locked=True)
    run_id = session.scalar(stmt)
    if run_id is None:
        return None
    result = session.execute(
        sa.update(Run)
        .where(Run.id == run_id, Run.state == RunState.QUEUED, Run.owner_pid.is_(None))
        .values(state=RunState.RUNNING, owner_pid=owner_pid, owner_host=owner_host, heartbeat_at=now)
        .execution_options(synchronize_session="fetch")
    )
    if getattr(result, "rowcount", 0) != 1:
        return None
    notify_run(session, run_id)
    run = session.get(Run, run_id, populate_existing=True)
    assert run is not None
    unit = session.get(Unit, run.unit_id)
    params = dict(run.params)
    point = None
    if params.get(RESUME_KEY):
        try:
            point = resume_point(session, run_id)
        except ValueError as exc:  # the recording changed since the request: not resumable now
            run.state, run.owner_pid, run.owner_host = RunState.INTERRUPTED, None, None
            run.error = f"interrupted: the queued resume was refused: {exc}"
            run.params = {k: v for k, v in params.items() if k != RESUME_KEY}
            session.flush()
            return None
        session.execute(
            sa.delete(SampleChunk).where(SampleChunk.run_id == run_id, SampleChunk.seq >= point.keep_chunks)
        )
        run.resume_count += 1
        run.error = None
        run.params = {k: v for k, v in params.items() if k not in (RESUME_KEY, ABORT_KEY, FINISHING_KEY)}
        session.flush()
    return ClaimedRun(
        run_id,
        unit.serial if unit is not None else "?",
        getattr(unit, "model", None),
        run.procedure,
        params,
        point,
    )


def queue_resume(session: Session, run_id: str, *, now: dt.datetime | None = None) -> ResumePoint | None:
    """Queue an ``interrupted`` run to continue on its bench; where it will pick up (as of now),
    or ``None`` if it is not interrupted.

    :raises ValueError: its recording cannot be cut at a window boundary (named).
    """
    point = resume_point(session, run_id)  # refuse now what the claim would refuse later
    run = session.get(Run, run_id, with_for_update=True)
    if run is None or run.state is not RunState.INTERRUPTED:
        return None
    dropped = (ABORT_KEY, CONTROL_KEY, FINISHING_KEY, "service_finished")
    params = {k: v for k, v in run.params.items() if k not in dropped}
    run.params = {**params, RESUME_KEY: True}
    run.state = RunState.QUEUED
    run.owner_pid, run.owner_host = None, None
    run.heartbeat_at = now or utc_now()
    session.flush()
    notify_run(session, run_id)
    return point


def request_control(
    session: Session, run_id: str, action: ControlAction, reason: str = ""
) -> RunState | None:
    """Ask the owner of a live run to ``abort``, ``pause`` or ``continue``.

    A queued run nobody has claimed is aborted at once (it never touched the table); a pause or
    continue asked of it is stored for its agent, which applies it once it has claimed the run.
    Returns the run's state after the request, or ``None`` when the request does not apply:
    the run is final or interrupted, or finishing (every step done, :func:`enter_finishing`), or
    a continue with no pause in effect or asked (a continue right after a pause the owner has
    not applied yet is accepted and undoes it); pause of a paused run is accepted, idempotent.

    :raises LookupError: no such run.
    """
    run = session.get(Run, run_id, with_for_update=True, populate_existing=True)
    if run is None:
        raise LookupError(f"run {run_id} not found")
    if run.state is RunState.QUEUED and run.owner_pid is None and action == "abort":
        now = utc_now()
        run.state, run.outcome, run.finished_at, run.heartbeat_at = RunState.ABORTED, "ABORTED", now, now
        run.error = f"aborted before it started: {reason or 'operator abort'}"
        session.flush()
        notify_run(session, run_id)
        return run.state
    if run.state not in (RunState.QUEUED, *HOLDING_STATES) or run.params.get(FINISHING_KEY):
        return None
    prev = run.params.get(CONTROL_KEY)
    newest = prev.get("action") if isinstance(prev, dict) else None
    if action == "continue" and run.state not in (RunState.PAUSED, RunState.SUSPENDED) and newest != "pause":
        return None  # nothing holds the run: no pause in effect, none asked
    if action == "abort":
        run.params = {**run.params, ABORT_KEY: reason or "operator abort"}
    else:
        seq = int(prev["seq"]) + 1 if isinstance(prev, dict) else 1
        run.params = {**run.params, CONTROL_KEY: {"seq": seq, "action": action}}
    session.flush()
    return run.state


def enter_finishing(session: Session, run_id: str, *, now: dt.datetime | None = None) -> str | None:
    """The owner has done every step of ``run_id``: the abort stored for it, if any (the run
    then ends ABORTED), else ``None`` with the run marked finishing, so that from this
    transaction on :func:`request_control` refuses abort, pause and continue.

    :raises LookupError: no such run.
    """
    run = session.get(Run, run_id, with_for_update=True, populate_existing=True)
    if run is None:
        raise LookupError(f"run {run_id} not found")
    abort = run.params.get(ABORT_KEY)
    if abort:
        return str(abort)
    run.params = {**run.params, FINISHING_KEY: (now or utc_now()).isoformat()}
    session.flush()
    return None


def finishing_since(session: Session, run_id: str) -> str | None:
    """When the run's owner began finishing it (ISO 8601), ``None`` when it has not."""
    params = session.scalar(sa.select(Run.params).where(Run.id == run_id)) or {}
    since = params.get(FINISHING_KEY)
    return str(since) if since else None


@dataclasses.dataclass(frozen=True)
class PendingControl:
    """What an owner has been asked: ``abort`` (the reason, or ``None``) and the newest pause or
    continue request (``seq``, ``action``; seq 0: none)."""

    abort: str | None
    seq: int
    action: str | None


def pending_control(session: Session, run_id: str) -> PendingControl:
    """The control requests stored for ``run_id`` (none for an unknown run)."""
    params = session.scalar(sa.select(Run.params).where(Run.id == run_id)) or {}
    abort = params.get(ABORT_KEY)
    ctl = params.get(CONTROL_KEY)
    if isinstance(ctl, dict):
        return PendingControl(str(abort) if abort else None, int(ctl.get("seq", 0)), str(ctl.get("action")))
    return PendingControl(str(abort) if abort else None, 0, None)


def bench_id_of(session: Session, name: str) -> int | None:
    """The id of the bench called ``name``, if it exists."""
    return session.scalar(sa.select(Bench.id).where(Bench.name == name))
