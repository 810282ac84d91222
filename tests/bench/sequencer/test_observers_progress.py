"""The run's observers told as one (an observer's failure named) and the progress event."""

from __future__ import annotations

import pytest

from bench.procedures import build_procedure, preview
from bench.records import GapRecord, RunState, StateChange
from bench.run_observer import NullObserver
from bench.sequencer.observers import ObserverError, Observers
from bench.sequencer.progress import RemainingTime, run_progress

GAP = GapRecord(100, 5, "dropped", 100, 1.0, 1.05, 2, "pos02", "window re-measured")


class Log(NullObserver):
    def __init__(self, name: str, log: list[str]) -> None:
        self.name, self.log = name, log

    def on_state(self, run_id: str, change: StateChange) -> None:
        self.log.append(f"{self.name} {run_id} {change.state.name}")


class Broken(NullObserver):
    def on_state(self, run_id: str, change: StateChange) -> None:
        raise RuntimeError("disk full")


class NoGapHook:
    """An observer written before the optional ``on_gap`` hook existed."""

    def on_state(self, run_id: str, change: StateChange) -> None:
        return None


def test_every_observer_is_told_in_order_and_a_failure_names_the_observer() -> None:
    log: list[str] = []
    Observers([Log("a", log), Log("b", log)]).notify(
        "on_state", "r1", StateChange(RunState.PAUSED, "operator")
    )
    assert log == ["a r1 PAUSED", "b r1 PAUSED"]
    log.clear()
    with pytest.raises(ObserverError, match=r"observer Broken\.on_state failed: RuntimeError: disk full"):
        Observers([Log("a", log), Broken(), Log("c", log)]).notify(
            "on_state", "r1", StateChange(RunState.RUNNING)
        )
    assert log == ["a r1 RUNNING"]  # the ones after the failing observer are not told


def test_the_gap_hook_is_optional() -> None:
    seen: list[tuple[str, GapRecord]] = []

    class Gaps(NullObserver):
        def on_gap(self, run_id: str, gap: GapRecord) -> None:
            seen.append((run_id, gap))

    Observers([NoGapHook(), Gaps()]).gap("r2", GAP)  # type: ignore[list-item]
    assert seen == [("r2", GAP)]


def test_a_run_at_a_steady_pace_is_predicted_exactly_from_its_first_window() -> None:
    """A run taking r times every nominal duration ends at r·T: from the first window done, the
    remaining time is that end minus the working time so far."""
    proc = build_procedure("static-12", settle_s=0.2, noise_window_s=30.0)
    pv = preview(proc, provisional_dwell_s=5.0)
    ends = [w.start_s + w.duration_s for w in pv.windows]
    eta = RemainingTime(proc, dwell_s=5.0)
    assert eta.remaining_s(0.0) == pytest.approx(pv.duration_s)  # nothing measured: the preview
    r = 0.7
    for k in (0, 3, 9):
        eta.window_done(k, r * ends[k])
        assert eta.ratio == pytest.approx(r)
        assert eta.remaining_s(r * ends[k]) == pytest.approx(r * pv.duration_s - r * ends[k])
    # part way to the next window's end: the same end, nearer
    w = r * (ends[9] + 0.5 * (ends[10] - ends[9]))
    assert eta.remaining_s(w) == pytest.approx(r * pv.duration_s - w)


def test_an_overrunning_window_keeps_the_rest_of_the_procedure_as_remaining() -> None:
    proc = build_procedure("static-12", settle_s=0.2, noise_window_s=30.0)
    eta = RemainingTime(proc, dwell_s=5.0)
    ends, total = eta.ends_s, eta.total_s
    eta.window_done(4, ends[4])
    # far past the projected end while window 5 is recorded: what follows window 5 is left
    assert eta.remaining_s(10 * total) == pytest.approx(total - ends[5])


def test_the_dwell_chosen_replans_and_a_resumed_run_measures_its_own_pace() -> None:
    proc = build_procedure("static-12", settle_s=0.2, noise_window_s=30.0)
    eta = RemainingTime(proc)  # no dwell yet: the preview's provisional one
    assert eta.total_s == pytest.approx(preview(proc).duration_s)
    eta.set_dwell(3.0)
    assert eta.total_s == pytest.approx(preview(proc, provisional_dwell_s=3.0).duration_s)
    # resumed at window 5 with 1000 s on the clock; twice the nominal time since
    res = RemainingTime(proc, first_window=5, start_work_s=1000.0, dwell_s=3.0)
    ends, total = res.ends_s, res.total_s
    res.window_done(7, 1000.0 + 2.0 * (ends[7] - ends[4]))
    assert res.ratio == pytest.approx(2.0)
    assert res.remaining_s(1000.0 + 2.0 * (ends[7] - ends[4])) == pytest.approx(2.0 * (total - ends[7]))


def test_the_progress_event_counts_working_time_only() -> None:
    proc = build_procedure("static-12", dwell_s=1.0, settle_s=0.2, noise_window_s=30.0)
    n = proc.n_windows
    p = run_progress(proc, 3, 6, 5, 90.0, 60.0, (0.0, 0.0, 0.0), RunState.RUNNING)
    assert p.expected_total_s == pytest.approx(150.0)
    assert (p.step_index, p.n_steps, p.window_index, p.n_windows) == (3, len(proc.steps), 6, n)
    # held 50 s of 90: 40 s worked, 60 s to go -> 40 % of the work done, still while held
    p = run_progress(proc, 3, 6, 5, 90.0, 60.0, (0.0, 0.0, 0.0), RunState.PAUSED, held_s=50.0)
    assert p.fraction == pytest.approx(40.0 / 100.0)
    # a step index past the end (the run finishing) labels the last step
    p = run_progress(proc, len(proc.steps) + 2, None, n, 200.0, 0.0, (1.0, 2.0, 3.0), RunState.RUNNING)
    assert p.step_label == getattr(proc.steps[-1], "label", "") and p.fraction == 1.0
