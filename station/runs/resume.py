"""Resumable runs of the service: a shutdown leaves the live run ``interrupted``, and an
interrupted run continues on this bench from the window after its last complete one.

A deploy restart must not destroy a long calibration. On shutdown the runner stops the run
with :data:`SHUTDOWN_REASON` (the sequencer makes the table safe and closes the recording
with every durable chunk) and :func:`interrupt_shutdown_abort` turns the stored ``aborted``
into ``interrupted``. Should the process die between the two writes,
:func:`recover_shutdown_aborts` (called at start-up) finishes the conversion: the reason
text marks such runs.

:func:`claim` hands an interrupted run to this process exactly once (``db.repo.recovery``)
and :func:`execute` continues it through the sequencer with the same simulated unit the run
started with, so the resumed recording is one measurement of one sensor.
"""

from __future__ import annotations

import dataclasses
import os
import socket
from collections.abc import Sequence
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from bench.records import RunRecord
from bench.run_observer import RunObserver
from bench.sequencer.control import RunControl
from db.models import SYSTEM, Run, RunState, Unit
from db.repo.audit import record_state
from db.repo.queue import ClaimedRun
from db.repo.recovery import ResumePoint, claim_for_resume
from db.types import utc_now
from drivers.factory import SimulatedTruth
from station.execution.continuation import continue_run
from station.execution.resume_admission import admit_resume
from station.runs.live import RunKind
from station.settings import Settings

SHUTDOWN_REASON = "service shutdown: resumable after the restart"
"""The abort reason of a run stopped by a service shutdown (it is in the stored error)."""


class NotResumable(Exception):
    """The run exists but cannot be resumed (HTTP 409); the message says why."""


def interrupt_shutdown_abort(session: Session, run_id: str) -> bool:
    """Turn a run ``aborted`` by a service shutdown into ``interrupted``; False if it is not."""
    result = session.execute(
        sa.update(Run)
        .where(Run.id == run_id, Run.state == RunState.ABORTED, Run.error.contains(SHUTDOWN_REASON))
        .values(
            state=RunState.INTERRUPTED,
            outcome=None,
            finished_at=None,
            heartbeat_at=utc_now(),
            error="interrupted: the service shut down during the run (table made safe, recording "
            f"closed); resume it with POST /api/runs/{run_id}/resume",
        )
        .execution_options(synchronize_session="fetch")
    )
    changed = bool(getattr(result, "rowcount", 0) == 1)
    if changed:
        record_state(session, run_id, RunState.INTERRUPTED, SYSTEM, "the service shut down during the run")
    return changed


def recover_shutdown_aborts(session: Session) -> list[str]:
    """Convert every run left ``aborted`` by a shutdown to ``interrupted``; their ids."""
    ids = session.scalars(
        sa.select(Run.id).where(Run.state == RunState.ABORTED, Run.error.contains(SHUTDOWN_REASON))
    ).all()
    return [run_id for run_id in ids if interrupt_shutdown_abort(session, run_id)]


@dataclasses.dataclass(frozen=True)
class Claimed:
    """An interrupted run this process now owns, with what its continuation needs.

    :param kind: ``calibration`` or ``drift_check`` (``Run.kind``; a run
        started from the CLI counts as a calibration).
    :param sim_age_days: age of the simulated unit at the run's start, ``None`` when the run
        was not started by the service's simulated bench (the seed's unit is used then).
    """

    run_id: str
    unit_serial: str
    model: str | None
    procedure: str
    params: dict[str, Any]
    point: ResumePoint
    kind: RunKind
    sim_age_days: float | None


def check_resumable(session: Session, run_id: str, settings: Settings | None = None) -> Run:
    """The run, if it can be resumed now; with ``settings``, also on this bench (its procedure
    from the window after its last complete one against the bench's table limits,
    :func:`~station.execution.resume_admission.admit_resume`).

    :raises LookupError: no such run. :raises NotResumable: its state forbids it.
    :raises ResumeRefused: (``settings`` given) its procedure is unknown here, no longer
        rebuilds from its stored parameters, or what remains breaks the table's limits.
    """
    run = session.get(Run, run_id)
    if run is None:
        raise LookupError(f"run {run_id} not found")
    if run.state is not RunState.INTERRUPTED:
        raise NotResumable(
            f"run {run_id} is {run.state.value}: only an interrupted run can be resumed "
            "(a paused or suspended run on this bench continues with the same request)"
        )
    if not run.recording_path:
        raise NotResumable(f"run {run_id} has no recording path stored: nothing to continue")
    if settings is not None:
        admit_resume(settings, run)
    return run


def claim(session: Session, run_id: str, actor: str = SYSTEM) -> Claimed:
    """Claim ``run_id`` for this process (exactly once among concurrent claimers), asked by
    ``actor`` (stored in the run's audit trail).

    :raises LookupError: no such run. :raises NotResumable: not interrupted, or its recording
        cannot be cut at a window boundary (the message names the chunk or window).
    """
    run = check_resumable(session, run_id)
    try:
        point = claim_for_resume(
            session, run_id, owner_pid=os.getpid(), owner_host=socket.gethostname(), actor=actor
        )
    except ValueError as exc:
        raise NotResumable(str(exc)) from None
    return from_queue(ClaimedRun.of(run, session.get(Unit, run.unit_id), point))


def from_queue(queued: ClaimedRun) -> Claimed:
    """The :class:`Claimed` of a claimed resume (``queued.point`` set): from the queue by an
    agent, or by :func:`claim` in this process."""
    if queued.point is None:
        raise ValueError(f"run {queued.run_id} was queued as a fresh run, not a resume")
    kind: RunKind = "drift_check" if queued.kind == "drift_check" else "calibration"
    return Claimed(
        queued.run_id,
        queued.unit_serial,
        queued.model,
        queued.procedure,
        queued.params,
        queued.point,
        kind,
        queued.sim_age_days,
    )


def execute(
    settings: Settings,
    sessions: Any,
    claimed: Claimed,
    *,
    truth: SimulatedTruth | None,
    observers: Sequence[RunObserver] = (),
    control: RunControl | None = None,
    defer_final_state: bool = False,
) -> RunRecord:
    """Continue a claimed run from ``claimed.point`` to its verdict (the fit as a fresh run's),
    with the same simulated unit it started with (``truth``; ``None``: the stored seed's).

    :param sessions: database session factory (the run's database observer writes with it).
    """
    return continue_run(
        settings,
        sessions,
        claimed.run_id,
        claimed.unit_serial,
        claimed.model,
        claimed.procedure,
        claimed.params,
        claimed.point,
        sim=settings.sim,
        truth=truth,
        observers=observers,
        control=control,
        defer_final_state=defer_final_state,
    )
