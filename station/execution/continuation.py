"""Continuing an interrupted bench run from the window after its last complete one.

:func:`resume_run` is what ``calbench resume`` calls: it claims the ``interrupted`` run in the
database (a run whose procedure no longer rebuilds, or whose remaining steps break the table's
limits, is refused and left as it was) and hands it to :func:`continue_run`, which the service's
resume (:mod:`station.runs.resume`) calls with a run it claimed itself. The recording is cut to
its last durable chunk holding the last complete window, the procedure rebuilt from the
parameters the recording stored, and the run executed to its verdict on the bench it started on
(:func:`station.execution.session.execute_resumable`). A run that never recorded starts from its
first step (:func:`station.execution.session.start_run`).
"""

from __future__ import annotations

import os
import socket
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench.procedures import preview
from bench.records import DwellChoice, RunRecord, RunStart
from bench.run_observer import RunObserver
from bench.run_recorder import RunRecorder
from bench.sequencer.control import RunControl
from bench.sequencer.loop import Sequencer
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Run, Unit
from db.models import RunState as DbRunState
from db.models import run_params as rp
from db.observer import DbRunObserver
from db.repo.audit import command_line_actor
from db.repo.recovery import ResumePoint, claim_for_resume, mark_interrupted_runs
from drivers.factory import SimulatedTruth
from station.execution.devices import bench_config_for, open_devices
from station.execution.fault_retry import ResumeFailed, disk_full_is_a_try
from station.execution.not_answering import interrupt_if_not_answering
from station.execution.resume_admission import admit_resume, admit_stored, request_keywords
from station.execution.session import execute_resumable, sequencer_config, start_run
from station.execution.verdict import limits_for
from station.settings import Settings


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
    config = sequencer_config(settings, bench_config)
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
