"""Composition of one new bench run: devices, database, recording, sequencer, fit.

:func:`start_run` is what ``calbench run`` (and the service's runner) calls. It opens the
table and DAQ from the settings (``sim://`` starts a simulated bench speaking the real
protocols), creates the run in the database (or takes the one this process claimed from the
queue), writes the recording under ``<data_dir>/recordings``, executes the procedure and, when
every step completed, fits the recording and gives the verdict (:func:`execute_resumable`: a
run a recoverable fault ended is left ``interrupted`` instead).

An interrupted run is continued by :mod:`station.execution.continuation`. The devices and the
bench file are :mod:`station.execution.devices`; the fit, the verdict and the observers' end of
a run :mod:`station.execution.verdict`.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench.bench_config import BenchConfig, apply_to_daq
from bench.dwell_policy import fixed_dwell
from bench.limits import LimitsChoice, UnitLimits
from bench.procedures import admit_procedure
from bench.records import DwellChoice, RunRecord, RunStart, new_run_id
from bench.run_observer import RunObserver, announce_phase
from bench.run_recorder import RunRecorder
from bench.run_state import RunState
from bench.sequencer.control import RunControl, SequencerConfig
from bench.sequencer.loop import Sequencer
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Run
from db.models import RunState as DbRunState
from db.observer import DbRunObserver
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from drivers.factory import BenchDevices, SimulatedTruth
from station.execution.devices import bench_config_for, bench_sidecar, open_devices
from station.execution.fault_retry import FAULT_PREFIX, ResumeFailed
from station.execution.not_answering import StartRequest, bench_urls, interrupt_if_not_answering
from station.execution.verdict import finish_observers, limits_for, run_record
from station.settings import Settings


def sequencer_config(settings: Settings, bench_config: BenchConfig) -> SequencerConfig:
    """The sequencer's configuration on the bench of ``bench_config`` (its table's limits)."""
    return SequencerConfig(limits=bench_config.table_limits(), temp_band_c=settings.temp_band_c)


def start_run(
    settings: Settings,
    procedure_name: str,
    unit_serial: str,
    *,
    sim: bool = False,
    sim_speed: float | None = None,
    seed: int = 0,
    dwell_s: float | None = None,
    observers: Sequence[RunObserver] = (),
    control: RunControl | None = None,
    g_local_m_s2: float | None = None,
    run_id: str | None = None,
    truth: SimulatedTruth | None = None,
    devices: BenchDevices | None = None,
    config: SequencerConfig | None = None,
    limits: UnitLimits | str | None = "settings",
    procedure_kw: dict[str, Any] | None = None,
    defer_final_state: bool = False,
) -> RunRecord:
    """Run a procedure on the bench from start to verdict.

    :param defer_final_state: leave the finished run's stored state live for the caller to
        finalise with what it stores after the run (``db.observer.finish_record``).

    :param procedure_kw: the procedure's own parameters (e.g. ``rates_deg_s``), stored with the
        run so a resume rebuilds the same steps.
    :param limits: the limits that give PASS or FAIL; default ``"settings"``:
        :func:`limits_for` the unit's registered model; ``None``: no limits, a completed fit gets
        no verdict (no statement of conformity).

    :param config: sequencer deadlines and policies; default from the settings, with the bench
        file's table limits.
    :param devices: devices already open (the caller keeps them and closes them); default:
        opened here from ``sim`` / the settings and closed at the end.

    :param run_id: the run's id when the caller allocated it (the service answers with it
        before the run starts); default :func:`new_run_id`.
    :param truth: the simulated unit (``sim`` only), e.g. an aged one; default the seed's.
    :param g_local_m_s2: local gravity (m/s²) overriding the bench file's.
    :raises ValueError: unknown procedure, a limit violation in the preview, bad dwell, a
        bench file that is missing (real bench), invalid or not the opened devices' bench.
    """
    bench_config = bench_config_for(settings, sim or (devices is not None and devices.sim is not None))
    config = config or sequencer_config(settings, bench_config)
    admitted = admit_procedure(procedure_name, config.limits, dwell_s=dwell_s, parameters=procedure_kw)
    proc, pv = admitted.procedure, admitted.preview
    dwell: DwellChoice | None = fixed_dwell(dwell_s) if dwell_s is not None else None
    engine = open_database(settings.effective_database_url)
    sessions = make_session_factory(engine)
    run_id = run_id or new_run_id(unit_serial)
    csv_path = settings.recordings_dir / f"run-{run_id}.csv"
    meta: dict[str, Any] = {
        "run_id": run_id,
        "procedure": procedure_name,
        "parameters": proc.parameters,
        "sim": {"seed": seed} if sim else None,
        "bench": settings.bench_name,
        "bench_config": bench_config.identity(),
    }
    owned = devices is None
    if devices is None:
        try:
            devices = open_devices(settings, sim, sim_speed, seed, truth, bench_config)
        except Exception as exc:
            try:
                why = interrupt_if_not_answering(
                    sessions,
                    run_id,
                    exc,
                    request=StartRequest(
                        settings, bench_config, unit_serial, procedure_name, meta, csv_path, dwell_s
                    ),
                )
            finally:
                engine.dispose()
            if why is None:
                raise
            raise ResumeFailed(why, run_id) from exc
    try:
        sidecar = bench_sidecar(devices, unit_serial, procedure_name, bench_config, g_local_m_s2)
        # devices opened here are already checked and mapped (open_devices); the caller's are not
        daq = devices.daq if owned else apply_to_daq(bench_config, devices.daq)
        with sessions.begin() as s:
            bench = get_or_create_bench(s, settings.bench_name, **bench_urls(bench_config))
            unit = get_or_create_unit(s, unit_serial, channel_unit=sidecar.channel_unit, bench_id=bench.id)
            if limits == "settings":  # before the run exists: a bad limits file refuses the run
                choice = limits_for(settings, getattr(unit, "model", None), sidecar.channel_unit)
            elif isinstance(limits, UnitLimits):
                choice = LimitsChoice(limits)
            else:
                choice = LimitsChoice(None, "no limits were given for this run")
            queued = s.get(Run, run_id, with_for_update=True)
            if queued is None:
                create_run(
                    s,
                    run_id,
                    unit.id,
                    procedure_name,
                    bench_id=bench.id,
                    params=meta,
                    recording_path=str(csv_path),
                    state=DbRunState.RUNNING,
                    owner_pid=os.getpid(),
                    owner_host=socket.gethostname(),
                )
            else:  # claimed from the queue by this process (db.repo.queue.claim_next_run)
                owner = (queued.owner_pid, queued.owner_host)
                if queued.state is not DbRunState.RUNNING or owner != (os.getpid(), socket.gethostname()):
                    raise ValueError(
                        f"run {run_id} is {queued.state.value} owned by {owner[0]}@{owner[1]}: "
                        "not claimed by this process"
                    )
                queued.recording_path = str(csv_path)
                queued.params = {**queued.params, **meta}
                s.flush()
        recorder = RunRecorder.create(csv_path, sidecar, has_temp=True, run_meta=meta)
        if dwell is not None:
            recorder.record_dwell(dwell)
        start = RunStart(
            run_id,
            unit_serial,
            procedure_name,
            settings.bench_name,
            str(csv_path),
            sidecar.sample_rate_hz,
            devices.table.n_axes,
            proc.n_windows,
            pv.duration_s,
            dwell=dwell,
            parameters=meta,
        )
        obs = [DbRunObserver(sessions, defer_final_state=defer_final_state), *observers]
        seq = Sequencer(
            devices.table,
            daq,
            proc,
            recorder,
            start,
            obs,
            control,
            config,
            dwell,
        )
        return execute_resumable(seq, csv_path, obs, choice, settings)
    finally:
        if owned:
            devices.close()
        engine.dispose()


def execute_resumable(
    seq: Sequencer,
    csv_path: Path,
    observers: Sequence[RunObserver],
    limits: LimitsChoice,
    settings: Settings,
) -> RunRecord:
    """:func:`station.execution.verdict.execute`, except that a run ended by a fault the bench recovers
    from (:func:`bench.sequencer.faults.resumable_fault`) is left ``interrupted`` — table safe,
    recording closed at its last durable chunk — with an error beginning
    :data:`~station.execution.fault_retry.FAULT_PREFIX`, for :mod:`station.execution.fault_retry`
    to resume."""
    acq = seq.run()
    if acq.resumable:
        record = RunRecord(
            start=seq.start,
            state=RunState.INTERRUPTED,
            outcome=None,
            windows=acq.windows,
            error=FAULT_PREFIX + (acq.error or "unknown"),
            n_samples=acq.n_samples,
            dwell=acq.dwell,
            gaps=acq.gaps,
        )
    else:
        if acq.outcome is None:  # every step done: the fit and the verdict follow
            announce_phase(observers, seq.start.run_id, "analysing")
        record = run_record(seq, acq.outcome, acq.error, csv_path, limits, settings)
    finish_observers(observers, record)
    return record
