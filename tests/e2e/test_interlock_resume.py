"""An interlock trip suspends the run; the operator's resume re-closes the interlock and the run
completes, recording the interrupted window again."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.recording.reader import read_recording
from bench.records import StateChange, WindowRecord
from bench.run_observer import NullObserver
from bench.run_state import Outcome, RunState
from bench.sequencer.control import RunControl, SequencerConfig
from drivers.factory import BenchDevices, open_bench
from drivers.sim.physics import SensorTruth
from station.execution.devices import sim_url
from station.execution.session import start_run
from tests.e2e.helpers import SIM_SPEED, settings_for, z_scores

pytestmark = pytest.mark.slow


class Operator(NullObserver):
    """Trips the interlock after window 1; answers the suspension with a resume."""

    def __init__(self, devices: BenchDevices, control: RunControl) -> None:
        self.devices, self.control = devices, control
        self.states: list[StateChange] = []

    def on_window(self, run_id: str, window: WindowRecord) -> None:
        if window.index == 1:
            self.devices.sim.controller.inject("interlock_trip", after_s=0.0)  # type: ignore[union-attr]

    def on_state(self, run_id: str, change: StateChange) -> None:
        self.states.append(change)
        if change.state is RunState.SUSPENDED:
            self.control.resume()


def test_operator_resume_after_an_interlock_trip_completes_the_run(tmp_path: Path) -> None:
    settings = settings_for(tmp_path)
    devices = open_bench(sim_url(settings, SIM_SPEED, 8))
    control = RunControl()
    operator = Operator(devices, control)
    try:
        record = start_run(
            settings,
            "static-12",
            "SN-ILK",
            sim=True,
            seed=8,
            dwell_s=5.0,
            observers=[operator],
            control=control,
            devices=devices,
            config=SequencerConfig(suspend_timeout_s=120.0),
        )
        assert record.outcome is Outcome.PASS, record.error
        states = [s.state for s in operator.states]
        assert states[:3] == [RunState.RUNNING, RunState.SUSPENDED, RunState.RUNNING], operator.states
        assert "interlock" in operator.states[1].reason
        assert operator.states[2].reason.startswith("resumed after")
        rec = read_recording(record.start.recording_path)
        labels = [s.label for s in rec.sidecar.segments or ()]
        assert labels == [f"pos{i:02d}" for i in range(1, 13)]  # each window once, none lost
        assert np.all(np.diff(rec.t_s) > 0)
        assert record.calibration is not None
        assert np.max(np.abs(z_scores(record.calibration.fitted_model(), SensorTruth.typical("V", 8)))) < 4.5
        assert devices.table.status().interlock_ok is False  # made safe at the end
    finally:
        devices.close()
