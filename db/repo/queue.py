"""The run queue of the benches: API processes queue runs and control requests, each bench's
agent claims the next run of its bench and follows the requests.

A queued run is a ``run`` row in state ``queued`` with no owner (``owner_pid`` NULL). The
agent of its bench claims it with :func:`claim_next_run`: in one transaction it locks the
bench row (``SELECT … FOR UPDATE`` on PostgreSQL; on SQLite every writing transaction begins
``IMMEDIATE`` and is alone anyway), checks that no other run of the bench is live, picks the
oldest queued run with ``SELECT … FOR UPDATE SKIP LOCKED`` (PostgreSQL) and moves it to
``running`` with a conditional ``UPDATE … WHERE state = 'queued'``: of two agents (or two
claims) exactly one gets it, and a bench never runs two runs at once.

Control requests (abort, pause, continue) are written into the run's columns by
:func:`request_control`; the agent reads them with :func:`pending_control`. An abort is
sticky (``run.abort_request``, its reason); pause and continue are a numbered request
(``run.control_seq``, ``run.control_action``): the agent applies the newest one it has not
applied, from the claim on, so a pause asked of a run still waiting in the queue holds it as
soon as it starts. A resume of an ``interrupted`` run is queued like a fresh run
(:func:`queue_resume`, ``run.resume_requested``); the claim then computes where the
recording is cut and deletes the chunk rows after it, as :func:`db.repo.recovery.claim_for_resume`.
Every request is an audit row (``run_audit``) with the operator who made it.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from typing import Any, Literal

import sqlalchemy as sa
from sqlalchemy.orm import Session

from bench.run_state import HOLDING_STATES
from db.models import SYSTEM, AuditAction, Bench, Run, RunState, SampleChunk, Unit
from db.notify import notify_run
from db.repo.audit import record_action, record_resume, record_state
from db.repo.lease import lease_is_current
from db.repo.recovery import ResumePoint, resume_point
from db.types import utc_now

ControlAction = Literal["abort", "pause", "continue"]
_ACTION = {"abort": AuditAction.ABORT, "pause": AuditAction.PAUSE, "continue": AuditAction.CONTINUE}


@dataclasses.dataclass(frozen=True)
class ClaimedRun:
    """A run an agent has just claimed.

    :param params: the run's parameters as stored.
    :param point: where a resumed run picks up; ``None`` for a fresh run.
    :param kind: ``calibration``/``drift_check`` (``Run.kind``), ``None``: not queued by the service.
    :param requested_dwell_s: the dwell the request asked for (s), ``None``: decided by the run.
    :param sim_age_days: the simulated unit's age the run started with (``None``: not stored).
    """

    run_id: str
    unit_serial: str
    model: str | None
    procedure: str
    params: dict[str, Any]
    point: ResumePoint | None
    kind: str | None = None
    requested_dwell_s: float | None = None
    sim_age_days: float | None = None

    @classmethod
    def of(cls, run: Run, unit: Unit | None, point: ResumePoint | None) -> ClaimedRun:
        """The claim of ``run`` (its unit, where it picks up)."""
        return cls(
            run.id,
            unit.serial if unit is not None else "?",
            getattr(unit, "model", None),
            run.procedure,
            dict(run.params),
            point,
            run.kind,
            run.requested_dwell_s,
            run.sim_age_days,
        )


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
    kind: str | None = None,
    requested_dwell_s: float | None = None,
    drift_night: str | None = None,
    actor: str = SYSTEM,
    now: dt.datetime | None = None,
) -> Run:
    """Add a run ``queued`` for the bench, with no owner (an agent claims it), and the audit row
    of its start request by ``actor``.

    :param kind: ``calibration`` or ``drift_check``; :param drift_night: a drift check's night.
    """
    now = now or utc_now()
    run = Run(
        id=run_id,
        unit_id=unit_id,
        bench_id=bench_id,
        procedure=procedure,
        state=RunState.QUEUED,
        progress=0.0,
        params=dict(params),
        kind=kind,
        requested_dwell_s=requested_dwell_s,
        drift_night=drift_night,
        created_at=now,
        heartbeat_at=now,
    )
    session.add(run)
    session.flush()
    dwell = f", dwell {requested_dwell_s:g} s" if requested_dwell_s is not None else ""
    record_action(session, run_id, AuditAction.START, actor, detail=f"{procedure}{dwell}", at=now)
    return run


def holding_run(session: Session, bench_id: int) -> Run | None:
    """The run that holds the bench (running, paused or suspended), if any."""
    return session.scalars(
        sa.select(Run).where(Run.bench_id == bench_id, Run.state.in_(list(HOLDING_STATES))).limit(1)
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
    point = None
    if run.resume_requested:
        try:
            point = resume_point(session, run_id)
        except ValueError as exc:  # the recording changed since the request: not resumable now
            run.state, run.owner_pid, run.owner_host = RunState.INTERRUPTED, None, None
            run.error = f"interrupted: the queued resume was refused: {exc}"
            run.resume_requested = False
            session.flush()
            record_state(session, run_id, RunState.INTERRUPTED, SYSTEM, run.error, at=now)
            return None
        session.execute(
            sa.delete(SampleChunk).where(SampleChunk.run_id == run_id, SampleChunk.seq >= point.keep_chunks)
        )
        run.resume_count += 1
        run.error = None
        run.resume_requested, run.abort_request, run.finishing_since = False, None, None
        session.flush()
    return ClaimedRun.of(run, unit, point)


def queue_resume(
    session: Session, run_id: str, *, actor: str = SYSTEM, now: dt.datetime | None = None
) -> ResumePoint | None:
    """Queue an ``interrupted`` run to continue on its bench (asked by ``actor``, an audit row);
    where it will pick up (as of now), or ``None`` if it is not interrupted.

    :raises ValueError: its recording cannot be cut at a window boundary (named).
    """
    point = resume_point(session, run_id)  # refuse now what the claim would refuse later
    run = session.get(Run, run_id, with_for_update=True)
    if run is None or run.state is not RunState.INTERRUPTED:
        return None
    now = now or utc_now()
    run.abort_request, run.control_seq, run.control_action, run.final_event = None, 0, None, None
    run.finishing_since = None
    run.resume_requested = True
    run.state = RunState.QUEUED
    run.owner_pid, run.owner_host = None, None
    run.heartbeat_at = now
    session.flush()
    record_resume(session, run_id, actor, point.next_window_index, at=now)
    notify_run(session, run_id)
    return point


def request_control(
    session: Session, run_id: str, action: ControlAction, reason: str = "", *, actor: str = SYSTEM
) -> RunState | None:
    """Ask the owner of a live run to ``abort``, ``pause`` or ``continue`` (``actor`` asks: an
    audit row when the request applies).

    A queued run nobody has claimed is aborted at once (it never touched the table), its final
    event (``Run.final_event``) stored with it, so its event streams end at once; a pause or
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
    now = utc_now()
    if run.state is RunState.QUEUED and run.owner_pid is None and action == "abort":
        run.state, run.outcome, run.finished_at, run.heartbeat_at = RunState.ABORTED, "ABORTED", now, now
        run.error = f"aborted before it started: {reason or 'operator abort'}"
        # nothing more will be stored for it: its last event now, so its streams end at once
        run.final_event = {"state": RunState.ABORTED.value, "outcome": "ABORTED", "error": run.error}
        session.flush()
        record_action(session, run_id, AuditAction.ABORT, actor, detail=reason or "operator abort", at=now)
        record_state(session, run_id, RunState.ABORTED, SYSTEM, run.error, at=now)
        notify_run(session, run_id)
        return run.state
    if run.state not in (RunState.QUEUED, *HOLDING_STATES) or run.finishing_since is not None:
        return None
    newest = run.control_action if run.control_seq else None
    if action == "continue" and run.state not in (RunState.PAUSED, RunState.SUSPENDED) and newest != "pause":
        return None  # nothing holds the run: no pause in effect, none asked
    if action == "abort":
        run.abort_request = reason or "operator abort"
    else:
        run.control_seq, run.control_action = run.control_seq + 1, action
    session.flush()
    record_action(session, run_id, _ACTION[action], actor, detail=reason, at=now)
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
    if run.abort_request:
        return run.abort_request
    run.finishing_since = now or utc_now()
    session.flush()
    return None


def finishing_since(session: Session, run_id: str) -> str | None:
    """When the run's owner began finishing it (ISO 8601), ``None`` when it has not."""
    since = session.scalar(sa.select(Run.finishing_since).where(Run.id == run_id))
    return since.isoformat() if since is not None else None


@dataclasses.dataclass(frozen=True)
class PendingControl:
    """What an owner has been asked: ``abort`` (the reason, or ``None``) and the newest pause or
    continue request (``seq``, ``action``; seq 0: none)."""

    abort: str | None
    seq: int
    action: str | None


def pending_control(session: Session, run_id: str) -> PendingControl:
    """The control requests stored for ``run_id`` (none for an unknown run)."""
    row = session.execute(
        sa.select(Run.abort_request, Run.control_seq, Run.control_action).where(Run.id == run_id)
    ).one_or_none()
    if row is None:
        return PendingControl(None, 0, None)
    abort, seq, action = row
    return PendingControl(abort or None, int(seq or 0), action if seq else None)


def bench_id_of(session: Session, name: str) -> int | None:
    """The id of the bench called ``name``, if it exists."""
    return session.scalar(sa.select(Bench.id).where(Bench.name == name))
