"""Composition of one bench run: devices, database, recording, sequencer, fit.

:func:`start_run` and :func:`resume_run` are what ``calbench run`` / ``calbench resume``
(and the service's runner) call. They open the table and DAQ from the settings
(``sim://`` starts a simulated bench speaking the real protocols), create or claim the
run in the database, write the recording under ``<data_dir>/recordings``, execute the
procedure and, when every step completed, fit the recording and give the verdict.
"""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from api.certificates.conformity import check_uncertainties
from api.certificates.issue import limits_model_name, run_budget
from api.settings import Settings
from bench.bench_config import SIM_BENCH_FILE, BenchConfig, apply_to_daq, load_bench_config
from bench.calibration import CalibrationResult, calibrate_recording
from bench.dwell_policy import fixed_dwell
from bench.estimation.scalar_fit import PARAMETER_NAMES as SCALAR_NAMES
from bench.estimation.static_fit import PARAMETER_NAMES as STATIC_NAMES
from bench.limits import UnitLimits, describe, load_limits, verdict
from bench.procedures import build_procedure, preview
from bench.recording import Recording
from bench.recording.model import Sidecar
from bench.recording.reader import read_recording
from bench.records import (
    DwellChoice,
    LimitCheck,
    Outcome,
    RunObserver,
    RunRecord,
    RunStart,
    RunState,
    new_run_id,
)
from bench.run_recorder import RunRecorder
from bench.sequencer.control import RunControl, SequencerConfig
from bench.sequencer.loop import Sequencer
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Run, Unit
from db.models import RunState as DbRunState
from db.observer import DbRunObserver
from db.repo.recovery import ResumePoint, claim_for_resume, mark_interrupted_runs
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from drivers.factory import BenchDevices, open_bench
from drivers.sim.physics import SensorTruth


def sim_url(settings: Settings, speed: float | None, seed: int, unit: str = "V") -> str:
    """The ``sim://`` URL of a simulated bench with this speed, seed and channel unit."""
    speed = speed or settings.sim_speed
    return f"sim://?speed={speed:g}&rate={settings.sim_sample_rate_hz:g}&seed={seed}&unit={unit}"


def bench_config_for(settings: Settings, sim: bool) -> BenchConfig:
    """The bench file of the settings (``CALBENCH_BENCH_FILE``); without one, the simulated
    bench's (``--sim`` or a ``sim://`` table URL).

    :raises BenchConfigError: the file is unreadable or invalid (file and key named).
    :raises ValueError: a real bench without a bench file.
    """
    if settings.bench_file is not None:
        return load_bench_config(settings.bench_file)
    if sim or settings.table_url.lower().startswith("sim:"):
        return load_bench_config(SIM_BENCH_FILE)
    raise ValueError(
        f"table {settings.table_url!r} is a real bench: its geometry, local g and DAQ channels come from a "
        "bench file (CALBENCH_BENCH_FILE or --bench-file; format in docs/bench-config.md)"
    )


def _sim_geometry(config: BenchConfig) -> dict[str, Any]:
    return {
        "axes": [list(a.axis) for a in config.axes],
        "mount": np.array(config.mount_rotation, dtype=float),
        "lever_arm_m": config.lever_arm_m,
        "g_local_m_s2": config.gravity.g_local_m_s2,
    }


def open_devices(
    settings: Settings,
    sim: bool,
    sim_speed: float | None,
    seed: int,
    truth: SensorTruth | None = None,
    config: BenchConfig | None = None,
) -> BenchDevices:
    """Table and DAQ of the bench file ``config`` (default :func:`bench_config_for`): a
    simulated bench built to its geometry (``sim``, a ``sim://`` file, unit ``truth`` or the
    seed's typical one; in its own process when ``settings.sim_process``) or the file's URLs;
    the DAQ is checked against the file and its channels mapped to the sensor's x, y, z.
    """
    config = config or bench_config_for(settings, sim)
    n_axes = len(config.axes)
    if sim or config.simulated:
        url = sim_url(settings, sim_speed, seed, config.channel_unit)
        if not sim and settings.bench_file is None and settings.table_url.lower().startswith("sim:"):
            url = settings.table_url  # a sim:// table URL with its own parameters
        devices = open_bench(
            url,
            truth=truth,
            n_axes=n_axes,
            sim_geometry=_sim_geometry(config),
            sim_process=settings.sim_process,
        )
    else:
        devices = open_bench(config.table_url, config.daq_url, n_axes=n_axes)
    try:
        devices.daq = apply_to_daq(config, devices.daq)
    except BaseException:
        devices.close()
        raise
    return devices


def _vec3(v: Any) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def check_devices(devices: BenchDevices, config: BenchConfig) -> None:
    """The opened devices are the bench the file describes (axes; a simulation's geometry).

    :raises ValueError: they differ (the file named).
    """
    if devices.table.n_axes != len(config.axes):
        raise ValueError(
            f"{config.path}: table.axes lists {len(config.axes)} axes, the table has {devices.table.n_axes}"
        )
    if devices.sim is not None:
        geo = devices.sim.geometry
        same = (
            np.allclose(geo.axes, [a.axis for a in config.axes], atol=1e-9)
            and np.allclose(geo.mount_rotation, config.mount_rotation, atol=1e-9)
            and np.allclose(geo.lever_arm_m, config.lever_arm_m, atol=1e-12)
            and abs(devices.sim.g_local_m_s2 - config.gravity.g_local_m_s2) < 1e-9
        )
        if not same:
            raise ValueError(
                f"{config.path}: the simulated bench's axes, mount, lever arm or g differ from the bench file"
            )


def bench_sidecar(
    devices: BenchDevices,
    unit_serial: str,
    procedure: str,
    config: BenchConfig,
    g_local_m_s2: float | None = None,
) -> Sidecar:
    """The sidecar: units and rate from the DAQ, table geometry and local g from the bench file
    (``g_local_m_s2`` overrides the file's g).

    :raises ValueError: the devices are not the bench the file describes.
    """
    check_devices(devices, config)
    return Sidecar(
        unit_serial=unit_serial,
        channel_unit=devices.daq.channel_unit,
        sample_rate_hz=devices.daq.sample_rate_hz,
        g_local_m_s2=config.gravity.g_local_m_s2 if g_local_m_s2 is None else g_local_m_s2,
        procedure=procedure,
        table=config.table_geometry(),
    )


def fit_covariance(result: CalibrationResult) -> tuple[tuple[tuple[float, ...], ...], tuple[str, ...]]:
    """The fit's parameter covariance and the names of its rows (static, scalar or dynamic fit)."""
    dynamic = getattr(result, "fit", None)
    if dynamic is not None:
        names = tuple(dynamic.names)
    else:
        names = SCALAR_NAMES if result.method == "scalar" else STATIC_NAMES
    cov = tuple(tuple(float(v) for v in row) for row in np.asarray(result.cov, dtype=float))
    if len(cov) != len(names):
        raise ValueError(f"fit covariance is {len(cov)}x{len(cov)} for {len(names)} parameter names")
    return cov, names


def judged_uncertainties(
    rec: Recording, calibration: dict[str, Any], settings: Settings | None, g_check_n: int | None = None
) -> dict[str, float]:
    """The expanded uncertainty of each value the limits check: with ``settings``, as the
    certificate will state it (the uncertainty budget with the bench's Type B settings, needed
    by a guard band); without, or when no budget can be formed, the fit's Type A σ with k = 2
    (simple acceptance, where U is stated beside the verdict; the certificate states its own)."""
    budget = None
    if settings is not None:
        budget, _why = run_budget(rec, calibration, settings)
    return check_uncertainties(calibration, budget, g_check_n)


def _finish(
    seq: Sequencer,
    acq_outcome: Outcome | None,
    error: str | None,
    csv_path: Path,
    limits: UnitLimits | None,
    settings: Settings | None = None,
) -> RunRecord:
    calibration: dict[str, object] | None = None
    outcome = acq_outcome
    checks: tuple[LimitCheck, ...] = ()
    cov: tuple[tuple[float, ...], ...] | None = None
    names: tuple[str, ...] = ()
    rec: Recording | None = None
    if outcome is None:
        try:
            rec = read_recording(csv_path)
            result = calibrate_recording(rec)
            calibration = result.to_contract()
            cov, names = fit_covariance(result)
        except ValueError as exc:
            outcome, error = Outcome.ERROR, f"fit failed: {exc}"
    if calibration is not None and rec is not None:
        try:
            n_g = int(np.size(result.g_after.error_m_s2))
            # the budget (refits for a moving table) only where the decision needs it: a guard band
            guarded = limits is not None and limits.decision_rule == "guarded-acceptance"
            us = (
                judged_uncertainties(rec, calibration, settings if guarded else None, n_g) if limits else None
            )
            outcome, checks = verdict(calibration, limits, us)
        except ValueError as exc:
            outcome, error = Outcome.ERROR, f"limits check failed: {exc}"
        if outcome is Outcome.FAIL:
            error = "outside limits: " + "; ".join(describe(c) for c in checks if not c.passed)
    return RunRecord(
        start=seq.start,
        state=RunState.FINISHED,
        outcome=outcome,
        windows=tuple(seq.recorder.windows),
        error=error,
        calibration=calibration,
        limit_checks=checks,
        n_samples=seq.recorder.n_rows,
        dwell=seq.dwell,
        fit_covariance=cov,
        fit_param_names=names,
        gaps=tuple(seq.recorder.gaps),
    )


class RunNotStored(RuntimeError):
    """A run ended but an observer (the database) could not store its end; names both."""


def finish_observers(
    observers: Sequence[RunObserver], record: RunRecord, retry_s: float = 30.0, wait_s: float = 0.5
) -> None:
    """Tell every observer the run ended; a failing one (a database write refused: disk full,
    connection lost) is retried with growing waits for ``retry_s``, so a transient failure
    still stores the outcome instead of leaving the run ``running``.

    :raises RunNotStored: an observer still failed at the end (each one named).
    """
    problems = []
    for obs in observers:
        deadline = time.monotonic() + retry_s
        pause = wait_s
        while True:
            try:
                obs.on_finish(record)
                break
            except Exception as exc:  # any observer failure: retried, then reported
                if time.monotonic() + pause > deadline:
                    problems.append(f"{type(obs).__name__}: {type(exc).__name__}: {exc}")
                    break
                time.sleep(pause)
                pause = min(2 * pause, 5.0)
    if problems:
        outcome = record.outcome.value if record.outcome else record.state.value
        raise RunNotStored(
            f"run {record.run_id} ended {outcome} but its end could not be stored "
            f"(retried {retry_s:g} s): " + "; ".join(problems)
        )


def _execute(
    seq: Sequencer,
    csv_path: Path,
    observers: Sequence[RunObserver],
    limits: UnitLimits | None,
    settings: Settings | None = None,
) -> RunRecord:
    acq = seq.run()
    record = _finish(seq, acq.outcome, acq.error, csv_path, limits, settings)
    finish_observers(observers, record)
    return record


def _config(settings: Settings) -> SequencerConfig:
    return SequencerConfig(temp_band_c=settings.temp_band_c)


def limits_for(settings: Settings, model: str | None, channel_unit: str) -> UnitLimits | None:
    """The limits that judge a unit: its registered ``model`` if the limits file has it, else
    ``settings.limits_model``; ``None`` when neither applies to ``channel_unit`` outputs.

    :raises ValueError: the limits file is unreadable or malformed (named).
    """
    table = load_limits(settings.limits_file)
    name = limits_model_name(settings, model)
    chosen = table.get(name) if name else None
    return chosen if chosen is not None and chosen.channel_unit == channel_unit else None


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
    truth: SensorTruth | None = None,
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
        :func:`limits_for` the unit's registered model; ``None``: every completed fit PASSes.

    :param config: sequencer deadlines and policies; default from the settings.
    :param devices: devices already open (the caller keeps them and closes them); default:
        opened here from ``sim`` / the settings and closed at the end.

    :param run_id: the run's id when the caller allocated it (the service answers with it
        before the run starts); default :func:`new_run_id`.
    :param truth: the simulated unit (``sim`` only), e.g. an aged one; default the seed's.
    :param g_local_m_s2: local gravity (m/s²) overriding the bench file's.
    :raises ValueError: unknown procedure, a limit violation in the preview, bad dwell, a
        bench file that is missing (real bench), invalid or not the opened devices' bench.
    """
    proc = build_procedure(procedure_name, dwell_s=dwell_s, **(procedure_kw or {}))
    pv = preview(proc, (config or _config(settings)).limits)
    if not pv.ok:
        raise ValueError(f"{procedure_name}: " + "; ".join(pv.problems))
    dwell: DwellChoice | None = fixed_dwell(dwell_s) if dwell_s is not None else None
    engine = open_database(settings.effective_database_url)
    sessions = make_session_factory(engine)
    run_id = run_id or new_run_id(unit_serial)
    csv_path = settings.recordings_dir / f"run-{run_id}.csv"
    bench_config = bench_config_for(settings, sim or (devices is not None and devices.sim is not None))
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
        devices = open_devices(settings, sim, sim_speed, seed, truth, bench_config)
    try:
        sidecar = bench_sidecar(devices, unit_serial, procedure_name, bench_config, g_local_m_s2)
        # devices opened here are already checked and mapped (open_devices); the caller's are not
        daq = devices.daq if owned else apply_to_daq(bench_config, devices.daq)
        with sessions.begin() as s:
            urls = (
                {}
                if bench_config.simulated
                else {"table_url": bench_config.table_url, "daq_url": bench_config.daq_url}
            )
            bench = get_or_create_bench(s, settings.bench_name, **urls)
            unit = get_or_create_unit(s, unit_serial, channel_unit=sidecar.channel_unit, bench_id=bench.id)
            if limits == "settings":  # before the run exists: a bad limits file refuses the run
                limits = limits_for(settings, getattr(unit, "model", None), sidecar.channel_unit)
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
            (config or _config(settings)),
            dwell,
        )
        return _execute(seq, csv_path, obs, limits if isinstance(limits, UnitLimits) else None, settings)
    finally:
        if owned:
            devices.close()
        engine.dispose()


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
    """
    engine = open_database(settings.effective_database_url)
    sessions = make_session_factory(engine)
    try:
        with sessions.begin() as s:
            mark_interrupted_runs(s, socket.gethostname())
            run = s.get(Run, run_id)
            if run is None:
                raise ValueError(f"run {run_id!r} not found in {settings.effective_database_url}")
            try:
                point = claim_for_resume(s, run_id, owner_pid=os.getpid(), owner_host=socket.gethostname())
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
    truth: SensorTruth | None = None,
    observers: Sequence[RunObserver] = (),
    control: RunControl | None = None,
    defer_final_state: bool = False,
) -> RunRecord:
    """Continue a run claimed for resumption from ``point`` to its verdict.

    The recording is cut to the last durable chunk holding the last complete window; the
    procedure is rebuilt from the parameters stored in the recording's run metadata (falling
    back to the run row's ``params``); the simulated unit is ``truth`` or the stored seed's.
    Shared by ``calbench resume`` and the service's resume.
    """
    csv_path = Path(str(point.recording_path))
    recorder = RunRecorder.resume(csv_path, point.keep_end_byte, point.next_window_index, point.keep_chunks)
    stored = recorder.run_meta
    parameters = dict(stored.get("parameters", params.get("parameters", {})))  # type: ignore[call-overload]
    dwell_s = parameters.pop("dwell_s", None)
    proc = build_procedure(procedure_name, dwell_s=dwell_s, **parameters_for(procedure_name, parameters))
    dwell_dict = stored.get("dwell")
    dwell = DwellChoice(**dwell_dict) if isinstance(dwell_dict, dict) else None  # type: ignore[arg-type]
    sim_meta = stored.get("sim") or params.get("sim")
    seed = int(sim_meta.get("seed", 0)) if isinstance(sim_meta, dict) else 0
    config = _config(settings)
    bench_config = bench_config_for(settings, sim)
    started_with = stored.get("bench_config")
    if isinstance(started_with, dict) and started_with.get("sha256") != bench_config.sha256:
        raise ValueError(
            f"run {run_id} started with bench file {started_with.get('name')!r} version "
            f"{started_with.get('version')} ({started_with.get('path')}); the bench file now is "
            f"{bench_config.name!r} version {bench_config.version} ({bench_config.path}), with other "
            "contents: a run continues only on the bench it started on"
        )
    devices = open_devices(settings, sim, sim_speed, seed, truth, bench_config)
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
        return _execute(seq, csv_path, obs, limits, settings)
    finally:
        devices.close()


def parameters_for(procedure_name: str, stored: dict[str, Any]) -> dict[str, Any]:
    """Procedure keyword arguments from stored parameters (those the factory accepts, non-null)."""
    import inspect

    from bench.procedures import PROCEDURES

    accepted = set(inspect.signature(PROCEDURES[procedure_name]).parameters) - {"dwell_s"}
    out = {k: v for k, v in stored.items() if k in accepted and v is not None}
    for k, v in list(out.items()):
        if isinstance(v, list):
            out[k] = tuple(tuple(x) if isinstance(x, list) else x for x in v)
    return out
