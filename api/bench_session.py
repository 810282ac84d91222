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
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from api.settings import Settings
from bench.calibration import CalibrationResult, calibrate_recording
from bench.dwell_policy import fixed_dwell
from bench.estimation.scalar_fit import PARAMETER_NAMES as SCALAR_NAMES
from bench.estimation.static_fit import PARAMETER_NAMES as STATIC_NAMES
from bench.limits import UnitLimits, describe, load_limits, verdict
from bench.procedures import build_procedure, preview
from bench.recording.model import Sidecar, TableAxis, TableGeometry
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
from bench.sequencer import Sequencer
from bench.sequencer_control import RunControl, SequencerConfig
from db.engine import make_session_factory, open_database
from db.models import Run, Unit
from db.models import RunState as DbRunState
from db.observer import DbRunObserver
from db.repo.recovery import ResumePoint, claim_for_resume, mark_interrupted_runs
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from drivers.factory import BenchDevices, open_bench
from drivers.sim.physics import SensorTruth

AXIS_NAMES = ("outer", "middle", "inner")


def sim_url(settings: Settings, speed: float | None, seed: int) -> str:
    """The ``sim://`` URL of a simulated bench with this speed and seed."""
    speed = speed or settings.sim_speed
    return f"sim://?speed={speed:g}&rate={settings.sim_sample_rate_hz:g}&seed={seed}&unit=V"


def open_devices(
    settings: Settings, sim: bool, sim_speed: float | None, seed: int, truth: SensorTruth | None = None
) -> BenchDevices:
    """Table and DAQ: a simulated bench (``sim``, unit ``truth`` or the seed's typical one;
    in its own process when ``settings.sim_process``) or the URLs of the settings."""
    if sim:
        return open_bench(sim_url(settings, sim_speed, seed), truth=truth, sim_process=settings.sim_process)
    return open_bench(settings.table_url, settings.daq_url)


def _vec3(v: Any) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def bench_sidecar(devices: BenchDevices, unit_serial: str, procedure: str, g_local_m_s2: float) -> Sidecar:
    """The sidecar: units from the DAQ, geometry from the (simulated) bench's belief."""
    n = devices.table.n_axes
    if devices.sim is not None:
        geo = devices.sim.geometry
        axes = tuple(
            TableAxis(AXIS_NAMES[i] if n == 3 else f"axis{i + 1}", _vec3(geo.axes[i])) for i in range(n)
        )
        mount = (_vec3(geo.mount_rotation[0]), _vec3(geo.mount_rotation[1]), _vec3(geo.mount_rotation[2]))
        table = TableGeometry(axes, mount, _vec3(geo.lever_arm_m))
        g_local_m_s2 = devices.sim.g_local_m_s2
    else:
        default = ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
        table = TableGeometry(tuple(TableAxis(AXIS_NAMES[i], default[i]) for i in range(n)))
    return Sidecar(
        unit_serial=unit_serial,
        channel_unit=devices.daq.channel_unit,
        sample_rate_hz=devices.daq.sample_rate_hz,
        g_local_m_s2=g_local_m_s2,
        procedure=procedure,
        table=table,
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


def _finish(
    seq: Sequencer, acq_outcome: Outcome | None, error: str | None, csv_path: Path, limits: UnitLimits | None
) -> RunRecord:
    calibration: dict[str, object] | None = None
    outcome = acq_outcome
    checks: tuple[LimitCheck, ...] = ()
    cov: tuple[tuple[float, ...], ...] | None = None
    names: tuple[str, ...] = ()
    if outcome is None:
        try:
            result = calibrate_recording(read_recording(csv_path))
            calibration = result.to_contract()
            cov, names = fit_covariance(result)
        except ValueError as exc:
            outcome, error = Outcome.ERROR, f"fit failed: {exc}"
    if calibration is not None:
        try:
            outcome, checks = verdict(calibration, limits)
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
    )


def _execute(
    seq: Sequencer, csv_path: Path, observers: Sequence[RunObserver], limits: UnitLimits | None
) -> RunRecord:
    acq = seq.run()
    record = _finish(seq, acq.outcome, acq.error, csv_path, limits)
    for obs in observers:
        obs.on_finish(record)
    return record


def _config(settings: Settings) -> SequencerConfig:
    return SequencerConfig(temp_band_c=settings.temp_band_c)


def limits_for(settings: Settings, model: str | None, channel_unit: str) -> UnitLimits | None:
    """The limits that judge a unit: its registered ``model`` if the limits file has it, else
    ``settings.limits_model``; ``None`` when neither applies to ``channel_unit`` outputs.

    :raises ValueError: the limits file is unreadable or malformed (named).
    """
    table = load_limits(settings.limits_file)
    name = model if model in table else settings.limits_model
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
    g_local_m_s2: float = 9.80665,
    run_id: str | None = None,
    truth: SensorTruth | None = None,
    devices: BenchDevices | None = None,
    config: SequencerConfig | None = None,
    limits: UnitLimits | str | None = "settings",
    procedure_kw: dict[str, Any] | None = None,
) -> RunRecord:
    """Run a procedure on the bench from start to verdict.

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
    :raises ValueError: unknown procedure, a limit violation in the preview, bad dwell.
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
    meta: dict[str, Any] = {
        "run_id": run_id,
        "procedure": procedure_name,
        "parameters": proc.parameters,
        "sim": {"seed": seed} if sim else None,
        "bench": settings.bench_name,
    }
    owned = devices is None
    if devices is None:
        devices = open_devices(settings, sim, sim_speed, seed, truth)
    try:
        sidecar = bench_sidecar(devices, unit_serial, procedure_name, g_local_m_s2)
        with sessions.begin() as s:
            bench = get_or_create_bench(s, settings.bench_name)
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
        obs = [DbRunObserver(sessions), *observers]
        seq = Sequencer(
            devices.table,
            devices.daq,
            proc,
            recorder,
            start,
            obs,
            control,
            (config or _config(settings)),
            dwell,
        )
        return _execute(seq, csv_path, obs, limits if isinstance(limits, UnitLimits) else None)
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
    devices = open_devices(settings, sim, sim_speed, seed, truth)
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
        obs = [DbRunObserver(sessions), *observers]
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
        return _execute(seq, csv_path, obs, limits)
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
