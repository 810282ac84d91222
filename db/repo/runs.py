"""Runs: creation, look-up, listing and the state transitions of their life cycle.

Transitions are conditional ``UPDATE … WHERE state IN (…)`` statements, never
read-modify-write, so two processes cannot both claim or finish the same run.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Collection
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from db.models import AGENT, FINAL_STATES, AuditAction, Run, RunState, Unit
from db.notify import notify_run
from db.repo._search import contains_any
from db.repo.audit import command_line_actor, record_action, record_state
from db.types import utc_now


def create_run(
    session: Session,
    run_id: str,
    unit_id: int,
    procedure: str,
    *,
    bench_id: int | None = None,
    params: dict[str, Any] | None = None,
    recording_path: str | None = None,
    state: RunState = RunState.QUEUED,
    owner_pid: int | None = None,
    owner_host: str | None = None,
    now: dt.datetime | None = None,
    actor: str | None = None,
) -> Run:
    """Add a run (default ``queued``) with the bench's ``run_id`` and flush, with the audit row
    of its start by ``actor`` (default: this machine's command-line user,
    :func:`db.repo.audit.command_line_actor`).

    :param params: procedure parameters, including the dwell choice and its reason (JSON-able).
    """
    if not procedure.strip():
        raise ValueError("procedure name must not be empty")
    if not run_id.strip() or len(run_id) > 64:
        raise ValueError(f"run id {run_id!r}: must be 1..64 characters")
    now = now or utc_now()
    run = Run(
        id=run_id,
        unit_id=unit_id,
        bench_id=bench_id,
        procedure=procedure,
        state=state,
        progress=0.0,
        params=dict(params or {}),
        recording_path=recording_path,
        owner_pid=owner_pid,
        owner_host=owner_host,
        heartbeat_at=now,
        started_at=now if state is RunState.RUNNING else None,
        created_at=now,
    )
    session.add(run)
    session.flush()
    record_action(session, run_id, AuditAction.START, actor or command_line_actor(), detail=procedure, at=now)
    return run


def get_run(session: Session, run_id: str, *, with_unit: bool = False) -> Run | None:
    """The run with ``run_id`` or ``None``; ``with_unit`` also loads ``run.unit``."""
    stmt = sa.select(Run).where(Run.id == run_id)
    if with_unit:
        stmt = stmt.options(selectinload(Run.unit))
    return session.scalars(stmt).one_or_none()


def list_runs(
    session: Session,
    *,
    unit_serial: str | None = None,
    states: Collection[RunState] | None = None,
    bench_id: int | None = None,
    limit: int | None = None,
    offset: int = 0,
    procedure: str | None = None,
    search: str | None = None,
) -> list[Run]:
    """Runs, newest first, with ``run.unit`` and ``run.bench`` loaded.

    :param offset: runs skipped from the newest (paging with ``limit``).
    :param procedure: only runs of this procedure.
    :param search: only runs whose id or unit serial contains this text (case-insensitive).
    """
    stmt = (
        sa.select(Run)
        .options(selectinload(Run.unit), selectinload(Run.bench))
        .order_by(Run.created_at.desc(), Run.id.desc())
    )
    if unit_serial is not None or search:
        stmt = stmt.join(Unit, Run.unit_id == Unit.id)
    if unit_serial is not None:
        stmt = stmt.where(Unit.serial == unit_serial)
    if search:
        stmt = stmt.where(contains_any(search, Run.id, Unit.serial))
    if procedure is not None:
        stmt = stmt.where(Run.procedure == procedure)
    if states is not None:
        stmt = stmt.where(Run.state.in_(list(states)))
    if bench_id is not None:
        stmt = stmt.where(Run.bench_id == bench_id)
    if offset:
        stmt = stmt.offset(offset)
    if limit is not None:
        stmt = stmt.limit(limit)
    return list(session.scalars(stmt))


def _update_run(
    session: Session, run_id: str, allowed_from: Collection[RunState], *, notify: bool = True, **values: Any
) -> bool:
    """``UPDATE run SET values WHERE id = run_id AND state IN allowed_from``; True if a row changed
    (and then, with ``notify``, the run's listeners are told at commit: :func:`db.notify.notify_run`)."""
    result = session.execute(
        sa.update(Run)
        .where(Run.id == run_id, Run.state.in_(list(allowed_from)))
        .values(**values)
        .execution_options(synchronize_session="fetch")
    )
    changed = bool(getattr(result, "rowcount", 0) == 1)
    if changed and notify:
        notify_run(session, run_id)
    return changed


def start_run(
    session: Session, run_id: str, *, owner_pid: int, owner_host: str, now: dt.datetime | None = None
) -> bool:
    """``queued`` -> ``running`` owned by ``owner_pid@owner_host``; False if not queued."""
    now = now or utc_now()
    return _update_run(
        session,
        run_id,
        [RunState.QUEUED],
        state=RunState.RUNNING,
        owner_pid=owner_pid,
        owner_host=owner_host,
        started_at=now,
        heartbeat_at=now,
    )


def heartbeat(
    session: Session, run_id: str, *, progress: float | None = None, now: dt.datetime | None = None
) -> bool:
    """Record a sign of life (and progress 0..1) of a live run; False if it is not live."""
    values: dict[str, Any] = {"heartbeat_at": now or utc_now()}
    if progress is not None:
        if not 0.0 <= progress <= 1.0:
            raise ValueError(f"run {run_id}: progress {progress!r} outside 0..1")
        values["progress"] = float(progress)
    live = [RunState.QUEUED, RunState.RUNNING, RunState.PAUSED, RunState.SUSPENDED]
    return _update_run(session, run_id, live, notify=False, **values)  # no event shows a heartbeat


def finish_run(
    session: Session,
    run_id: str,
    state: RunState,
    *,
    outcome: str | None = None,
    error: str | None = None,
    now: dt.datetime | None = None,
    actor: str = AGENT,
) -> bool:
    """Move a queued/running/suspended/interrupted run to a final ``state`` (an audit row by
    ``actor``, the run's owner by default).

    ``progress`` is set to 1 for ``completed``. False if the run was already final.
    """
    if state not in FINAL_STATES:
        raise ValueError(
            f"run {run_id}: {state.value!r} is not a final state ({sorted(s.value for s in FINAL_STATES)})"
        )
    now = now or utc_now()
    values: dict[str, Any] = {
        "state": state,
        "outcome": outcome,
        "error": error,
        "finished_at": now,
        "heartbeat_at": now,
    }
    if state is RunState.COMPLETED:
        values["progress"] = 1.0
    live = [s for s in RunState if s not in FINAL_STATES]
    changed = _update_run(session, run_id, live, **values)
    if changed:
        detail = error or (f"outcome {outcome}" if outcome else "")
        record_state(session, run_id, state, actor, detail, at=now)
    return changed


def set_live_state(
    session: Session,
    run_id: str,
    state: RunState,
    *,
    now: dt.datetime | None = None,
    reason: str = "",
    actor: str = AGENT,
) -> bool:
    """Move between live states (running, paused, suspended); False if the run is not live.
    The change is an audit row by ``actor`` (the run's owner by default) with ``reason`` and
    the window being recorded (the one after the last complete one)."""
    live = [RunState.QUEUED, RunState.RUNNING, RunState.PAUSED, RunState.SUSPENDED]
    if state not in live:
        raise ValueError(f"run {run_id}: {state.value!r} is not a live state")
    now = now or utc_now()
    changed = _update_run(session, run_id, live, state=state, heartbeat_at=now)
    if changed:
        last = session.scalar(sa.select(Run.last_complete_window).where(Run.id == run_id))
        window = 0 if last is None else last + 1
        record_state(session, run_id, state, actor, reason, window_index=window, at=now)
    return changed


def set_recording_path(session: Session, run_id: str, recording_path: str) -> None:
    """Record where the run's recording CSV is written."""
    session.execute(sa.update(Run).where(Run.id == run_id).values(recording_path=recording_path))


def merge_params(session: Session, run_id: str, extra: dict[str, Any]) -> None:
    """Add keys to a run's ``params`` (e.g. the dwell chosen from Allan analysis and why, the
    latest progress event); the run's listeners are told at commit."""
    run = session.get(Run, run_id, with_for_update=True)
    if run is None:
        raise LookupError(f"run {run_id} not found")
    run.params = {**run.params, **extra}
    session.flush()
    notify_run(session, run_id)


def set_certificate_error(session: Session, run_id: str, error: str) -> None:
    """Store why a completed run got no certificate (``Run.certificate_error``); the run's
    listeners are told at commit.

    :raises LookupError: no such run.
    """
    result = session.execute(sa.update(Run).where(Run.id == run_id).values(certificate_error=error))
    if getattr(result, "rowcount", 0) != 1:
        raise LookupError(f"run {run_id} not found")
    notify_run(session, run_id)


def set_service_run(session: Session, run_id: str, kind: str, *, sim_age_days: float | None = None) -> None:
    """Mark a run as the service's (``calibration`` or ``drift_check``) and, on a simulated
    bench, the age of the simulated unit it started with (a resume measures the same sensor).

    :raises LookupError: no such run.
    """
    values: dict[str, Any] = {"kind": kind}
    if sim_age_days is not None:
        values["sim_age_days"] = float(sim_age_days)
    result = session.execute(sa.update(Run).where(Run.id == run_id).values(**values))
    if getattr(result, "rowcount", 0) != 1:
        raise LookupError(f"run {run_id} not found")


def set_live_progress(session: Session, run_id: str, data: dict[str, Any]) -> None:
    """Store the run's latest ``progress`` event (``Run.live_progress``); listeners are told."""
    session.execute(sa.update(Run).where(Run.id == run_id).values(live_progress=dict(data)))
    notify_run(session, run_id)


def set_final_event(session: Session, run_id: str, data: dict[str, Any]) -> bool:
    """Store the run's last event (``Run.final_event``: its results are stored); listeners are
    told. False when there is no such run."""
    result = session.execute(sa.update(Run).where(Run.id == run_id).values(final_event=dict(data)))
    notify_run(session, run_id)
    return bool(getattr(result, "rowcount", 0) == 1)
