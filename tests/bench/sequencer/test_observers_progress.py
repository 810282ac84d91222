"""The run's observers told as one (an observer's failure named) and the progress event."""

from __future__ import annotations

import pytest

from bench.procedures import build_procedure
from bench.records import GapRecord, RunState, StateChange
from bench.run_observer import NullObserver
from bench.sequencer.observers import ObserverError, Observers
from bench.sequencer.progress import run_progress

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


def test_the_expected_duration_is_never_reached_before_the_last_window() -> None:
    proc = build_procedure("static-12", dwell_s=1.0, settle_s=0.2, noise_window_s=30.0)
    n = proc.n_windows
    k = n // 2
    # on schedule: 100 s preview, k of n windows done at 100 k / n s -> the preview holds
    p = run_progress(proc, 3, None, k, 100.0 * k / n, 100.0, (0.0, 0.0, 0.0), RunState.RUNNING)
    assert p.expected_total_s == pytest.approx(100.0)
    # late: at 90 s with n - k windows left, (n - k) / n of the preview more is expected
    p = run_progress(proc, 3, 6, k, 90.0, 100.0, (0.0, 0.0, 0.0), RunState.RUNNING)
    assert p.expected_total_s == pytest.approx(90.0 + 100.0 * (n - k) / n)
    assert (p.step_index, p.n_steps, p.window_index, p.n_windows) == (3, len(proc.steps), 6, n)
    # held 50 s of 90: the working time is 40 s, the bar where 40 s would put it
    p = run_progress(proc, 3, 6, k, 90.0, 100.0, (0.0, 0.0, 0.0), RunState.PAUSED, held_s=50.0)
    assert p.expected_total_s == pytest.approx(50.0 + 100.0)
    assert p.fraction == pytest.approx(40.0 / 100.0)
    # a step index past the end (the run finishing) labels the last step
    p = run_progress(proc, len(proc.steps) + 2, None, n, 200.0, 100.0, (1.0, 2.0, 3.0), RunState.RUNNING)
    assert p.step_label == getattr(proc.steps[-1], "label", "") and p.expected_total_s == 200.0
