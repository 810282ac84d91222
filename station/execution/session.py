"""Composition of one bench run: devices, database, recording, sequencer, fit.

:func:`start_run` and :func:`resume_run` are what ``calbench run`` / ``calbench resume``
(and the service's runner) call. They open the table and DAQ from the settings
(``sim://`` starts a simulated bench speaking the real protocols), create or claim the
run in the database, write the recording under ``<data_dir>/recordings``, execute the
procedure and, when every step completed, fit the recording and give the verdict.

The devices and the bench file are :mod:`station.execution.devices`; the fit, the verdict and the
observers' end of a run :mod:`station.execution.verdict`.
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
from bench.procedures import admit_procedure, preview
from bench.records import DwellChoice, RunRecord, RunStart, new_run_id
from bench.run_observer import RunObserver, announce_phase
from bench.run_recorder import RunRecorder
from bench.run_state import RunState
from bench.sequencer.control import RunControl, SequencerConfig
from bench.sequencer.loop import Sequencer
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Run, Unit
from db.models import RunState as DbRunState
from db.models import run_params as rp
from db.observer import DbRunObserver
from db.repo.audit import command_line_actor
from db.repo.recovery import ResumePoint, claim_for_resume, mark_interrupted_runs
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from drivers.factory import BenchDevices, SimulatedTruth
from station.execution.devices import bench_config_for, bench_sidecar, open_devices
from station.execution.fault_retry import FAULT_PREFIX, ResumeFailed, disk_full_is_a_try
from station.execution.not_answering import StartRequest, bench_urls, interrupt_if_not_answering
from station.execution.resume_admission import admit_resume, admit_stored, request_keywords
from station.execution.verdict import finish_observers, limits_for, run_record
from station.settings import Settings


def _config(settings: Settings, bench_config: BenchConfig) -> SequencerConfig:
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
    config = config or _config(settings, bench_config)
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


def resume_run(
    settings: Settings,
    run_id: str,
    *,
    sim: bool = False,
    sim_speed: float | None = None,
    observers: Sequence[RunObserver] = (),
    control: RunControl | None = None,
) -> RunRecord:
    """Resume an interrupted run from the window after its last complete one.

    :raises ValueError: no such run, or it is not resumable (the message says its state).
    :raises ResumeRefused: its procedure is unknown here, no longer rebuilds from its stored
        parameters, or what remains of it breaks the table's limits
        (:func:`~station.execution.resume_admission.admit_resume`).
    """
    engine = open_database(settings.effective_database_url)
    sessions = make_session_factory(engine)
    try:
        with disk_full_is_a_try(run_id, "the database refused its claim"), sessions.begin() as s:
            mark_interrupted_runs(s, socket.gethostname())
            run = s.get(Run, run_id)
            if run is None:
                raise ValueError(f"run {run_id!r} not found in {settings.effective_database_url}")
            if run.state is DbRunState.INTERRUPTED:  # another state: the claim below says so
                admit_resume(settings, run, sim)  # before the claim: a refused run is left as it was
            try:
                point = claim_for_resume(
                    s,
                    run_id,
                    owner_pid=os.getpid(),
                    owner_host=socket.gethostname(),
                    actor=command_line_actor(),
                )
            except LookupError as exc:
                raise ValueError(str(exc)) from exc
            procedure_name, params = run.procedure, dict(run.params)
            unit = s.get(Unit, run.unit_id)
            serial = unit.serial if unit is not None else "?"
            model = getattr(unit, "model", None)
        if point.recording_path is None:
            raise ValueError(f"run {run_id}: no recording path stored")
        return continue_run(
            settings,
            sessions,
            run_id,
            serial,
            model,
            procedure_name,
            params,
            point,
            sim=sim,
            sim_speed=sim_speed,
            observers=observers,
            control=control,
        )
    finally:
        engine.dispose()


def continue_run(
    settings: Settings,
    sessions: Any,
    run_id: str,
    serial: str,
    model: str | None,
    procedure_name: str,
    params: dict[str, Any],
    point: ResumePoint,
    *,
    sim: bool,
    sim_speed: float | None = None,
    truth: SimulatedTruth | None = None,
    observers: Sequence[RunObserver] = (),
    control: RunControl | None = None,
    defer_final_state: bool = False,
) -> RunRecord:
    """Continue a run claimed for resumption from ``point`` to its verdict.

    The recording is cut to the last durable chunk holding the last complete window; the
    procedure is rebuilt from the parameters stored in the recording's run metadata (falling
    back to the run row's ``params``); the simulated unit is ``truth`` or the stored seed's.
    Shared by ``calbench resume`` and the service's resume. A run that never recorded (its
    devices did not open when it started: no recording, no window) starts now from its first
    step, as it was requested.
    """
    if point.next_window_index == 0 and (
        point.recording_path is None or not Path(str(point.recording_path)).exists()
    ):
        with sessions.begin() as s:
            run = s.get(Run, run_id)
            requested_dwell_s = run.requested_dwell_s if run is not None else None
        stored = params.get(rp.PARAMETERS)
        procedure_kw = request_keywords(run_id, procedure_name, stored) if isinstance(stored, dict) else None
        sim_meta = params.get(rp.SIM)  # the seed it was requested with (calbench run --seed)
        seed = settings.sim_seed
        if isinstance(sim_meta, dict) and isinstance(sim_meta.get("seed"), int):
            seed = int(sim_meta["seed"])
        return start_run(
            settings,
            procedure_name,
            serial,
            sim=sim,
            sim_speed=sim_speed,
            seed=seed,
            dwell_s=requested_dwell_s,
            observers=observers,
            control=control,
            run_id=run_id,
            truth=truth,
            procedure_kw=procedure_kw,
            defer_final_state=defer_final_state,
        )
    csv_path = Path(str(point.recording_path))
    try:
        recorder = RunRecorder.resume(
            csv_path, point.keep_end_byte, point.next_window_index, point.keep_chunks
        )
    except OSError as exc:  # a full disk, an I/O error: a try of the retry policy, as a bench not answering
        if isinstance(exc, FileNotFoundError | PermissionError):  # not a fault that passes
            raise
        why = interrupt_if_not_answering(sessions, run_id, exc, "the recording could not be reopened")
        if why is None:
            raise
        raise ResumeFailed(why) from exc
    stored = recorder.run_meta
    stored_parameters = stored.get("parameters", params.get(rp.PARAMETERS, {}))
    if not isinstance(stored_parameters, dict):
        raise ValueError(f"{csv_path}: the stored procedure parameters are not a JSON object")
    bench_config = bench_config_for(settings, sim)
    config = _config(settings, bench_config)
    admitted = admit_stored(
        run_id, procedure_name, dict(stored_parameters), point.next_window_index, config.limits
    )
    proc = admitted.procedure
    dwell_dict = stored.get("dwell")
    dwell = DwellChoice(**dwell_dict) if isinstance(dwell_dict, dict) else None
    sim_meta = stored.get("sim") or params.get(rp.SIM)
    seed = int(sim_meta.get("seed", 0)) if isinstance(sim_meta, dict) else 0
    started_with = stored.get("bench_config")
    if isinstance(started_with, dict) and started_with.get("sha256") != bench_config.sha256:
        raise ValueError(
            f"run {run_id} started with bench file {started_with.get('name')!r} version "
            f"{started_with.get('version')} ({started_with.get('path')}); the bench file now is "
            f"{bench_config.name!r} version {bench_config.version} ({bench_config.path}), with other "
            "contents: a run continues only on the bench it started on"
        )
    try:
        devices = open_devices(settings, sim, sim_speed, seed, truth, bench_config)
    except Exception as exc:
        why = interrupt_if_not_answering(sessions, run_id, exc)
        if why is None:
            raise
        raise ResumeFailed(why) from exc
    try:
        start = RunStart(
            run_id,
            serial,
            procedure_name,
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
        obs = [DbRunObserver(sessions, defer_final_state=defer_final_state), *observers]
        seq = Sequencer(
            devices.table,
            devices.daq,
            proc,
            recorder,
            start,
            obs,
            control,
            config,
            dwell,
            start_window=point.next_window_index,
        )
        limits = limits_for(settings, model, devices.daq.channel_unit)
        return execute_resumable(seq, csv_path, obs, limits, settings)
    finally:
        devices.close()
