"""Composition of one bench run: devices, database, recording, sequencer, fit.

:func:`start_run` and :func:`resume_run` are what ``calbench run`` / ``calbench resume``
(and the service's runner) call. They open the table and DAQ from the settings
(``sim://`` starts a simulated bench speaking the real protocols), create or claim the
run in the database, write the recording under ``<data_dir>/recordings``, execute the
procedure and, when every step completed, fit the recording and give the verdict.
"""

from __future__ import annotations

import dataclasses
import math
import os
import socket
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sqlalchemy.orm import Session, sessionmaker

from api.settings import Settings
from bench.calibration import calibrate_recording
from bench.dwell_policy import fixed_dwell
from bench.procedures import build_procedure, preview
from bench.recording.model import Sidecar, TableAxis, TableGeometry
from bench.recording.reader import read_recording
from bench.records import (
    ChunkRecord,
    DwellChoice,
    NullObserver,
    Outcome,
    Progress,
    RunObserver,
    RunRecord,
    RunStart,
    RunState,
    StateChange,
    WindowRecord,
    new_run_id,
)
from bench.run_recorder import RunRecorder
from bench.sequencer import Sequencer
from bench.sequencer_control import RunControl, SequencerConfig
from db.engine import make_session_factory, open_database
from db.models import Run, Unit
from db.models import RunState as DbRunState
from db.repo.progress import record_chunk, record_window
from db.repo.recovery import claim_for_resume, mark_interrupted_runs
from db.repo.runs import create_run, finish_run, heartbeat, merge_params, set_live_state
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
    """Table and DAQ: a simulated bench (``sim``, unit ``truth`` or the seed's typical one)
    or the URLs of the settings."""
    if sim:
        return open_bench(sim_url(settings, sim_speed, seed), truth=truth)
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


_FINAL = {
    Outcome.PASS: DbRunState.COMPLETED,
    Outcome.FAIL: DbRunState.COMPLETED,
    Outcome.ERROR: DbRunState.ERROR,
    Outcome.ABORTED: DbRunState.ABORTED,
}
_LIVE = {
    RunState.RUNNING: DbRunState.RUNNING,
    RunState.PAUSED: DbRunState.PAUSED,
    RunState.SUSPENDED: DbRunState.SUSPENDED,
}


class DbObserver(NullObserver):
    """Writes a run's progress to the database through ``db.repo`` (one short transaction each).

    Chunks and windows are stored as they become durable, so a restart knows the last
    complete window; progress events become heartbeats (at most one per ``heartbeat_s``).
    """

    def __init__(self, sessions: sessionmaker[Session], heartbeat_s: float = 1.0) -> None:
        self.sessions = sessions
        self.heartbeat_s = heartbeat_s
        self._last_beat = 0.0

    def on_state(self, run_id: str, change: StateChange) -> None:
        if change.state in _LIVE:
            with self.sessions.begin() as s:
                set_live_state(s, run_id, _LIVE[change.state])

    def on_progress(self, run_id: str, progress: Progress) -> None:
        if time.monotonic() - self._last_beat >= self.heartbeat_s:
            self._last_beat = time.monotonic()
            with self.sessions.begin() as s:
                heartbeat(s, run_id, progress=progress.fraction)

    def on_chunk(self, run_id: str, chunk: ChunkRecord) -> None:
        with self.sessions.begin() as s:
            record_chunk(
                s,
                run_id,
                chunk.seq,
                first_sample=chunk.first_sample,
                n_samples=chunk.n_samples,
                last_t_s=chunk.last_t_s,
                end_byte=chunk.end_byte,
                window_index=chunk.window_index,
            )

    def on_window(self, run_id: str, window: WindowRecord) -> None:
        means = {k: (None if not math.isfinite(v) else v) for k, v in window.means.items()}
        with self.sessions.begin() as s:
            record_window(
                s,
                run_id,
                window.index,
                start_s=window.start_s,
                end_s=window.end_s,
                n_samples=window.n_samples,
                label=window.label,
                kind=window.kind.value,
                pose_deg=window.pose_deg,
                means=means,
                step_index=window.step_index,
            )

    def on_dwell(self, run_id: str, dwell: DwellChoice) -> None:
        with self.sessions.begin() as s:
            merge_params(s, run_id, {"dwell": dataclasses.asdict(dwell)})

    def on_finish(self, record: RunRecord) -> None:
        if record.outcome is None:
            return
        with self.sessions.begin() as s:
            if record.calibration is not None:
                merge_params(s, record.run_id, {"calibration": record.calibration})
            finish_run(
                s,
                record.run_id,
                _FINAL[record.outcome],
                outcome=record.outcome.value.lower(),
                error=record.error,
            )


def _finish(seq: Sequencer, acq_outcome: Outcome | None, error: str | None, csv_path: Path) -> RunRecord:
    calibration: dict[str, object] | None = None
    outcome = acq_outcome
    if outcome is None:
        try:
            calibration = calibrate_recording(read_recording(csv_path)).to_contract()
            outcome = Outcome.PASS  # no limits configured for the unit: the fit itself is the result
        except ValueError as exc:
            outcome, error = Outcome.ERROR, f"fit failed: {exc}"
    return RunRecord(
        start=seq.start,
        state=RunState.FINISHED,
        outcome=outcome,
        windows=tuple(seq.recorder.windows),
        error=error,
        calibration=calibration,
        n_samples=seq.recorder.n_rows,
        dwell=seq.dwell,
    )


def _execute(seq: Sequencer, csv_path: Path, observers: Sequence[RunObserver]) -> RunRecord:
    acq = seq.run()
    record = _finish(seq, acq.outcome, acq.error, csv_path)
    for obs in observers:
        obs.on_finish(record)
    return record


def _config(settings: Settings) -> SequencerConfig:
    return SequencerConfig(temp_band_c=settings.temp_band_c)


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
) -> RunRecord:
    """Run a procedure on the bench from start to verdict.

    :param config: sequencer deadlines and policies; default from the settings.
    :param devices: devices already open (the caller keeps them and closes them); default:
        opened here from ``sim`` / the settings and closed at the end.

    :param run_id: the run's id when the caller allocated it (the service answers with it
        before the run starts); default :func:`new_run_id`.
    :param truth: the simulated unit (``sim`` only), e.g. an aged one; default the seed's.
    :raises ValueError: unknown procedure, a limit violation in the preview, bad dwell.
    """
    proc = build_procedure(procedure_name, dwell_s=dwell_s)
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
        obs = [DbObserver(sessions), *observers]
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
        return _execute(seq, csv_path, obs)
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
        if point.recording_path is None:
            raise ValueError(f"run {run_id}: no recording path stored")
        csv_path = Path(point.recording_path)
        recorder = RunRecorder.resume(
            csv_path, point.keep_end_byte, point.next_window_index, point.keep_chunks
        )
        stored = recorder.run_meta
        parameters = dict(stored.get("parameters", params.get("parameters", {})))  # type: ignore[call-overload]
        dwell_s = parameters.pop("dwell_s", None)
        proc = build_procedure(procedure_name, dwell_s=dwell_s, **parameters_for(procedure_name, parameters))
        dwell_dict = stored.get("dwell")
        dwell = DwellChoice(**dwell_dict) if isinstance(dwell_dict, dict) else None  # type: ignore[arg-type]
        sim_meta = stored.get("sim") or params.get("sim")
        seed = int(sim_meta.get("seed", 0)) if isinstance(sim_meta, dict) else 0
        devices = open_devices(settings, sim, sim_speed, seed)
        try:
            pv = preview(proc, _config(settings).limits)
            start = RunStart(
                run_id,
                serial,
                procedure_name,
                settings.bench_name,
                str(csv_path),
                devices.daq.sample_rate_hz,
                devices.table.n_axes,
                proc.n_windows,
                pv.duration_s,
                dwell=dwell,
                parameters=dict(stored),
                resumed_from_window=point.next_window_index,
            )
            obs = [DbObserver(sessions), *observers]
            seq = Sequencer(
                devices.table,
                devices.daq,
                proc,
                recorder,
                start,
                obs,
                control,
                _config(settings),
                dwell,
                start_window=point.next_window_index,
            )
            return _execute(seq, csv_path, obs)
        finally:
            devices.close()
    finally:
        engine.dispose()


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
