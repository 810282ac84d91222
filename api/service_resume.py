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
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from api.bench_session import _execute, limits_for, open_devices, parameters_for
from api.settings import Settings
from bench.procedures import build_procedure, preview
from bench.records import DwellChoice, RunObserver, RunRecord, RunStart
from bench.run_recorder import RunRecorder
from bench.sequencer import Sequencer
from bench.sequencer_control import RunControl, SequencerConfig
from db.models import Run, RunState, Unit
from db.observer import DbRunObserver
from db.repo.recovery import ResumePoint, claim_for_resume
from db.types import utc_now
from drivers.sim.physics import SensorTruth

SHUTDOWN_REASON = "service shutdown: resumable after the restart"
"""The abort reason of a run stopped by a service shutdown (it is in the stored error)."""

SIM_AGE_KEY = "service_sim_age_days"
"""``Run.params`` key: age (days) of the simulated unit the run started with."""


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
    return bool(getattr(result, "rowcount", 0) == 1)


def recover_shutdown_aborts(session: Session) -> list[str]:
    """Convert every run left ``aborted`` by a shutdown to ``interrupted``; their ids."""
    ids = session.scalars(
        sa.select(Run.id).where(Run.state == RunState.ABORTED, Run.error.contains(SHUTDOWN_REASON))
    ).all()
    return [run_id for run_id in ids if interrupt_shutdown_abort(session, run_id)]


@dataclasses.dataclass(frozen=True)
class Claimed:
    """An interrupted run this process now owns, with what its continuation needs.

    :param kind: ``calibration`` or ``drift_check`` (``params["service_kind"]``; a run
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
    kind: str
    sim_age_days: float | None


def check_resumable(session: Session, run_id: str) -> Run:
    """The run, if it can be resumed now.

    :raises LookupError: no such run. :raises NotResumable: its state forbids it.
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
    return run


def claim(session: Session, run_id: str) -> Claimed:
    """Claim ``run_id`` for this process (exactly once among concurrent claimers).

    :raises LookupError: no such run. :raises NotResumable: not interrupted, or its recording
        cannot be cut at a window boundary (the message names the chunk or window).
    """
    run = check_resumable(session, run_id)
    try:
        point = claim_for_resume(session, run_id, owner_pid=os.getpid(), owner_host=socket.gethostname())
    except ValueError as exc:
        raise NotResumable(str(exc)) from None
    unit = session.get(Unit, run.unit_id)
    params = dict(run.params)
    kind = params.get("service_kind")
    age = params.get(SIM_AGE_KEY)
    return Claimed(
        run_id,
        unit.serial if unit is not None else "?",
        getattr(unit, "model", None),
        run.procedure,
        params,
        point,
        kind if kind in ("calibration", "drift_check") else "calibration",
        float(age) if isinstance(age, int | float) else None,
    )


def execute(
    settings: Settings,
    sessions: Any,
    claimed: Claimed,
    *,
    truth: SensorTruth | None,
    observers: Sequence[RunObserver] = (),
    control: RunControl | None = None,
) -> RunRecord:
    """Continue a claimed run from ``claimed.point`` to its verdict (the fit as a fresh run's).

    The recording is cut to the last durable chunk holding the last complete window; the
    procedure is rebuilt from the parameters stored in the recording's run metadata.

    :param sessions: database session factory (the run's database observer writes with it).
    :param truth: the simulated unit (``settings.sim``), ``None``: the stored seed's.
    """
    point = claimed.point
    csv_path = Path(str(point.recording_path))
    recorder = RunRecorder.resume(csv_path, point.keep_end_byte, point.next_window_index, point.keep_chunks)
    stored = recorder.run_meta
    parameters = dict(stored.get("parameters", claimed.params.get("parameters", {})))  # type: ignore[call-overload]
    dwell_s = parameters.pop("dwell_s", None)
    kwargs = parameters_for(claimed.procedure, parameters)
    proc = build_procedure(claimed.procedure, dwell_s=dwell_s, **kwargs)
    dwell_dict = stored.get("dwell")
    dwell = DwellChoice(**dwell_dict) if isinstance(dwell_dict, dict) else None  # type: ignore[arg-type]
    sim_meta = stored.get("sim") or claimed.params.get("sim")
    seed = int(sim_meta.get("seed", 0)) if isinstance(sim_meta, dict) else 0
    config = SequencerConfig(temp_band_c=settings.temp_band_c)
    devices = open_devices(settings, settings.sim, None, seed, truth)
    try:
        start = RunStart(
            claimed.run_id,
            claimed.unit_serial,
            claimed.procedure,
            settings.bench_name,
            str(csv_path),
            devices.daq.sample_rate_hz,
            devices.table.n_axes,
            proc.n_windows,
            preview(proc, config.limits).duration_s,
            dwell=dwell,
            parameters=dict(stored),
            resumed_from_window=point.next_window_index,
        )
        obs = [DbRunObserver(sessions), *observers]
        seq = Sequencer(devices.table, devices.daq, proc, recorder, start, obs, control, config, dwell,
                        start_window=point.next_window_index)
        limits = limits_for(settings, claimed.model, devices.daq.channel_unit)
        return _execute(seq, csv_path, obs, limits)
    finally:
        devices.close()
