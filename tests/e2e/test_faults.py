"""Injected driver faults on the simulated bench: a fault the device reports (an axis fault, a
Modbus exception) ends as a clean ERROR; one the bench recovers from (a controller that stops
answering, a garbled line, a DAQ that stays silent) leaves the run ``interrupted`` with the
reason, and a resume then completes it; in every case the table is made safe where it still
answers and the partial recording is kept.

Faults are injected into the simulated controller and DAQ server once the second window is
complete, through an observer; the real drivers see them over their real protocols.
"""

from __future__ import annotations

import errno
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.recording.reader import read_recording
from bench.records import RunRecord, StateChange, WindowRecord
from bench.run_observer import NullObserver
from bench.run_recorder import RunRecorder
from bench.run_state import Outcome, RunState
from bench.sequencer.control import RunControl, SequencerConfig
from drivers.base import AxisMode
from drivers.factory import BenchDevices, open_bench
from station.execution.continuation import resume_run
from station.execution.devices import sim_url
from station.execution.fault_retry import RetryPolicy, run_resuming
from station.execution.session import start_run
from tests.e2e.helpers import SIM_SPEED, settings_for

pytestmark = pytest.mark.slow

FAST_FAIL = SequencerConfig(
    stall_timeout_s=5.0, stop_timeout_s=5.0, move_timeout_margin_s=10.0, suspend_timeout_s=3.0
)


class InjectAfter(NullObserver):
    def __init__(self, window: int, inject: Callable[[], None]) -> None:
        self.window = window
        self.inject = inject
        self.states: list[StateChange] = []

    def on_window(self, run_id: str, window: WindowRecord) -> None:
        if window.index == self.window:
            self.inject()

    def on_state(self, run_id: str, change: StateChange) -> None:
        self.states.append(change)


def run_with_fault(
    tmp_path: Path, inject: Callable[[BenchDevices], None]
) -> tuple[RunRecord, BenchDevices, InjectAfter]:
    settings = settings_for(tmp_path)
    devices = open_bench(sim_url(settings, SIM_SPEED, 7))
    obs = InjectAfter(1, lambda: inject(devices))
    try:
        record = start_run(
            settings,
            "static-12",
            "SN-FAULT",
            sim=True,
            seed=7,
            dwell_s=5.0,
            observers=[obs],
            devices=devices,
            config=FAST_FAIL,
        )
    except BaseException:
        devices.close()
        raise
    return record, devices, obs


def assert_recording_kept(record: RunRecord) -> None:
    rec = read_recording(record.start.recording_path)
    assert rec.n_samples == record.n_samples > 0
    assert len(rec.sidecar.segments or ()) == len(record.windows) >= 2


def assert_table_safe(devices: BenchDevices) -> None:
    st = devices.table.status()
    assert all(a.mode is AxisMode.OFF and abs(a.rate_deg_s) < 1e-6 for a in st.axes), st
    assert not st.interlock_ok  # the shutdown order ends with the interlock open


def test_a_table_axis_fault_ends_as_error(tmp_path: Path) -> None:
    def inject(d: BenchDevices) -> None:
        d.sim.controller.inject("stalled_axis", axis=2, trip_s=0.5)  # type: ignore[union-attr]

    record, devices, _ = run_with_fault(tmp_path, inject)
    try:
        assert record.outcome is Outcome.ERROR and record.state is RunState.ERROR, record
        assert record.error is not None and "step" in record.error
        assert_recording_kept(record)
        assert_table_safe(devices)
    finally:
        devices.close()


def assert_interrupted_then_resumed(tmp_path: Path, record: RunRecord, expect: str) -> None:
    """The run stopped on a device fault: interrupted, resumable; a resume completes it."""
    assert record.state is RunState.INTERRUPTED and record.outcome is None, record
    assert record.error is not None and record.error.startswith("device fault: ") and expect in record.error
    assert_recording_kept(record)
    resumed = resume_run(settings_for(tmp_path), record.run_id, sim=True, sim_speed=SIM_SPEED)
    assert resumed.outcome is Outcome.PASS, resumed.error
    assert len(resumed.windows) == 12 and resumed.start.resumed_from_window == len(record.windows)


@pytest.mark.parametrize(
    ("fault", "params", "expect"), [("no_reply", {}, "Timeout"), ("garbled", {}, "Error")]
)
def test_a_table_that_stops_answering_or_garbles_leaves_the_run_resumable(
    tmp_path: Path, fault: str, params: dict[str, Any], expect: str
) -> None:
    def inject(d: BenchDevices) -> None:
        d.sim.controller.inject(fault, **params)  # type: ignore[union-attr]

    record, devices, _ = run_with_fault(tmp_path, inject)
    devices.close()
    assert_interrupted_then_resumed(tmp_path, record, expect)


def test_interlock_trip_suspends_then_errors_when_it_stays_open(tmp_path: Path) -> None:
    record, devices, obs = run_with_fault(
        tmp_path, lambda d: d.sim.controller.inject("interlock_trip", after_s=0.0)
    )  # type: ignore[union-attr]
    try:
        assert [s.state for s in obs.states][:2] == [RunState.RUNNING, RunState.SUSPENDED]
        assert "interlock" in obs.states[1].reason
        assert record.outcome is Outcome.ERROR and "suspended for more than 3 s" in (record.error or "")
        assert_recording_kept(record)
    finally:
        devices.close()


def test_a_daq_device_failure_ends_as_error_with_the_table_safe(tmp_path: Path) -> None:
    record, devices, _ = run_with_fault(tmp_path, lambda d: d.sim.daq_server.inject_exception(4, None))  # type: ignore[union-attr]
    try:
        assert record.outcome is Outcome.ERROR, record
        assert_recording_kept(record)
        assert_table_safe(devices)
    finally:
        devices.close()


def test_a_silent_daq_leaves_the_run_resumable_with_the_table_safe(tmp_path: Path) -> None:
    record, devices, _ = run_with_fault(tmp_path, lambda d: d.sim.daq_server.set_silent(True))  # type: ignore[union-attr]
    try:
        assert_table_safe(devices)
    finally:
        devices.close()
    assert_interrupted_then_resumed(tmp_path, record, "Timeout")


def test_lost_daq_samples_are_recorded_again_not_hidden(tmp_path: Path) -> None:
    record, devices, _ = run_with_fault(tmp_path, lambda d: d.sim.daq_server.drop_samples(30))  # type: ignore[union-attr]
    try:
        assert record.outcome is Outcome.PASS, record.error
        assert len(record.windows) == 12
        rec = read_recording(record.start.recording_path)
        jumps = rec.t_s[:-1][np.diff(rec.t_s) > 1.5 / rec.sidecar.sample_rate_hz]
        assert jumps.size >= 1  # the 30 lost samples show as a jump in t
        assert not any(w.start_s <= t < w.end_s for w in record.windows for t in jumps)
    finally:
        devices.close()


def test_a_daq_whose_server_closes_the_connection_leaves_the_run_resumable(tmp_path: Path) -> None:
    """The pymodbus server closes the Modbus TCP connection mid-run (a DAQ that resets its
    network, a dropped line): the run is interrupted as for a stalled table, and resumes."""
    closed: list[int] = []
    record, devices, _ = run_with_fault(
        tmp_path,
        lambda d: closed.append(d.sim.daq_server.drop_connections()),  # type: ignore[union-attr]
    )
    try:
        assert closed == [1]
        assert_table_safe(devices)
    finally:
        devices.close()
    assert_interrupted_then_resumed(tmp_path, record, "LinkLost")


class InjectAtStart(NullObserver):
    def __init__(self, inject: Callable[[], None]) -> None:
        self.inject = inject
        self.done = False

    def on_state(self, run_id: str, change: StateChange) -> None:
        if change.state is RunState.RUNNING and not self.done:
            self.done = True
            self.inject()


@pytest.mark.parametrize("fault", ["table", "daq line"])
def test_a_fault_before_the_first_window_leaves_the_run_resumable(tmp_path: Path, fault: str) -> None:
    settings = settings_for(tmp_path)
    devices = open_bench(sim_url(settings, SIM_SPEED, 7))
    sim = devices.sim
    assert sim is not None and sim.daq_server is not None
    inject = (
        (lambda: sim.controller.inject("no_reply")) if fault == "table" else sim.daq_server.drop_connections
    )
    try:
        record = start_run(
            settings, "static-12", "SN-EARLY", sim=True, seed=7, dwell_s=5.0,
            observers=[InjectAtStart(inject)], devices=devices, config=FAST_FAIL,
        )  # fmt: skip
    finally:
        devices.close()
    assert record.state is RunState.INTERRUPTED and record.windows == (), record
    assert record.error is not None and record.error.startswith("device fault: "), record.error
    resumed = resume_run(settings, record.run_id, sim=True, sim_speed=SIM_SPEED)
    assert resumed.outcome is Outcome.PASS, resumed.error
    assert len(resumed.windows) == 12 and resumed.start.resumed_from_window == 0


def test_a_disk_still_full_at_a_resume_counts_as_a_try_and_the_next_try_completes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The retry policy's tries are all made, each after its wait: a resume whose recording
    cannot be reopened because the disk is still full is a failed try (the run stays
    interrupted), not the end of the retries."""
    record, devices, _ = run_with_fault(tmp_path, lambda d: d.sim.controller.inject("no_reply"))  # type: ignore[union-attr]
    devices.close()
    assert record.state is RunState.INTERRUPTED, record
    real = RunRecorder.resume.__func__  # type: ignore[attr-defined]
    refused: list[str] = []

    def disk_full_twice(cls: type[RunRecorder], *args: Any, **kwargs: Any) -> RunRecorder:
        if len(refused) < 2:
            refused.append("ENOSPC")
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(cls, *args, **kwargs)  # type: ignore[no-any-return]

    monkeypatch.setattr(RunRecorder, "resume", classmethod(disk_full_twice))
    said: list[str] = []
    settings = settings_for(tmp_path)
    out = run_resuming(
        lambda: record,
        lambda run_id: resume_run(settings, run_id, sim=True, sim_speed=SIM_SPEED),
        RunControl(),
        said.append,
        RetryPolicy(attempts=4, first_wait_s=0.01, max_wait_s=0.05),
    )
    assert isinstance(out, RunRecord) and out.outcome is Outcome.PASS and len(out.windows) == 12, out.error
    assert refused == ["ENOSPC", "ENOSPC"]
    tries = [s for s in said if "resuming in" in s]
    assert [t.rsplit("(", 1)[1] for t in tries] == ["1/4)", "2/4)", "3/4)"], said
    failed = [s for s in said if "the resume failed" in s]
    assert len(failed) == 2 and all("No space left on device" in s for s in failed), said
