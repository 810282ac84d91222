"""Suspension, pause and the operator's resume, on the in-test devices of ``test_sequencer``."""

from __future__ import annotations

import threading
from pathlib import Path

from bench.records import WindowRecord
from bench.run_state import Outcome, RunState
from bench.sequencer.control import SequencerConfig
from tests.bench.sequencer.test_sequencer import FAST, FakeTable, make, quick_static


class LatchingTable(FakeTable):
    """An interlock that, once tripped, stays open until ``prepare`` resets it (as a real table)."""

    def __init__(self) -> None:
        super().__init__()
        self.prepared = 0

    def prepare(self, timeout_s: float) -> None:
        self.prepared += 1
        self.interlock_ok = True


def test_interlock_open_suspends_and_the_window_is_recorded_again(tmp_path: Path) -> None:
    seq, table, _, obs, _ = make(tmp_path, quick_static())

    def trip(w: WindowRecord) -> None:
        if w.index == 2:
            table.interlock_ok = False
            threading.Timer(0.3, lambda: setattr(table, "interlock_ok", True)).start()

    obs.hook = trip
    acq = seq.run()
    assert acq.outcome is None, acq.error
    assert [s.state for s in obs.states] == [RunState.RUNNING, RunState.SUSPENDED, RunState.RUNNING]
    assert "interlock open" in obs.states[1].reason
    assert [w.index for w in acq.windows] == list(range(12))
    assert [w.label for w in acq.windows] == [f"pos{i:02d}" for i in range(1, 13)]


def test_temperature_out_of_band_suspends_until_back(tmp_path: Path) -> None:
    cfg = SequencerConfig(**{**FAST.__dict__, "temp_band_c": (20.0, 30.0)})
    seq, _table, daq, obs, _ = make(tmp_path, quick_static(), config=cfg)

    def heat(w: WindowRecord) -> None:
        if w.index == 5:
            daq.temp_c = 35.0
            threading.Timer(0.3, lambda: setattr(daq, "temp_c", 25.0)).start()

    obs.hook = heat
    acq = seq.run()
    assert acq.outcome is None, acq.error
    suspended = [s for s in obs.states if s.state is RunState.SUSPENDED]
    assert len(suspended) == 1 and "35.00 °C outside its band [20, 30]" in suspended[0].reason
    assert len(acq.windows) == 12 and all(w.temp_c_mean == 25.0 for w in acq.windows)


def test_pause_and_resume(tmp_path: Path) -> None:
    seq, _table, _, obs, ctl = make(tmp_path, quick_static())

    def pause(w: WindowRecord) -> None:
        if w.index == 1:
            ctl.pause()
            threading.Timer(0.2, ctl.resume).start()

    obs.hook = pause
    acq = seq.run()
    assert acq.outcome is None
    assert [s.state for s in obs.states] == [RunState.RUNNING, RunState.PAUSED, RunState.RUNNING]
    assert len(acq.windows) == 12
    # the bar stands still while held: every progress event of the pause has one fraction,
    # though the recording clock went on
    held = [p for p in obs.progress if p.state is RunState.PAUSED]
    assert len(held) >= 2 and held[-1].elapsed_s > held[0].elapsed_s
    assert {round(p.fraction, 12) for p in held} == {round(held[0].fraction, 12)}
    assert held[-1].held_s > 0 and obs.progress[-1].held_s >= held[-1].held_s


def test_operator_resume_re_prepares_a_latched_interlock(tmp_path: Path) -> None:
    table = LatchingTable()
    seq, _table, _, obs, ctl = make(tmp_path, quick_static(), table=table)

    def trip(w: WindowRecord) -> None:
        if w.index == 3:
            table.interlock_ok = False
            threading.Timer(0.3, ctl.resume).start()

    obs.hook = trip
    acq = seq.run()
    assert acq.outcome is None, acq.error
    assert table.prepared == 2  # before the run, and on the operator's resume
    assert [s.state for s in obs.states] == [RunState.RUNNING, RunState.SUSPENDED, RunState.RUNNING]
    assert [w.label for w in acq.windows] == [f"pos{i:02d}" for i in range(1, 13)]


def test_a_resume_asked_before_the_trip_does_not_clear_it(tmp_path: Path) -> None:
    table = LatchingTable()
    cfg = SequencerConfig(**{**FAST.__dict__, "suspend_timeout_s": 1.0})
    seq, _table, _, obs, ctl = make(tmp_path, quick_static(), table=table, config=cfg)

    def trip(w: WindowRecord) -> None:
        if w.index == 0:
            ctl.resume()  # nothing to resume yet
        if w.index == 3:
            table.interlock_ok = False

    obs.hook = trip
    acq = seq.run()
    assert acq.outcome is Outcome.ERROR and "suspended for more than 1 s" in (acq.error or "")
    assert table.prepared == 1 and len(acq.windows) == 4
