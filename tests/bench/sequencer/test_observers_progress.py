"""The run's observers told as one (an observer's failure named) and the progress event."""

from __future__ import annotations

import pytest

from bench.procedures import build_procedure, preview
from bench.records import GapRecord, StateChange
from bench.run_observer import NullObserver
from bench.run_state import RunState
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


class NoPrior(RemainingTime):
    PRIOR_FRACTION = 0.0


def _actual_end(pv, k: int, r: float) -> float:
    """End of window k when windows last their length and everything else r times nominal."""
    windows = sum(w.duration_s for w in pv.windows[: k + 1])
    return windows + r * ((pv.windows[k].start_s + pv.windows[k].duration_s) - windows)


def test_moves_at_a_steady_pace_are_predicted_exactly_from_the_first_move_measured() -> None:
    """Moves and settling taking r times their nominal time, windows their length: the run ends
    at ΣD + r·(T − ΣD), and the remaining time is that end minus the working time so far."""
    proc = build_procedure("static-12", settle_s=0.2, noise_window_s=30.0)
    pv = preview(proc, provisional_dwell_s=5.0)
    windows = sum(w.duration_s for w in pv.windows)
    eta = NoPrior(proc, dwell_s=5.0)
    assert eta.remaining_s(0.0) == pytest.approx(pv.duration_s)  # nothing measured: the preview
    r = 4.0
    end = windows + r * (pv.duration_s - windows)
    for k in range(0, 10):
        eta.window_done(k, _actual_end(pv, k, r), pv.windows[k].duration_s)
    assert eta.ratio == pytest.approx(r)
    w9 = _actual_end(pv, 9, r)
    assert eta.remaining_s(w9) == pytest.approx(end - w9)
    w = w9 + 0.5 * (_actual_end(pv, 10, r) - w9)  # part way to the next window's end
    assert eta.remaining_s(w) == pytest.approx(end - w)


def test_the_prior_pulls_an_early_ratio_towards_one() -> None:
    proc = build_procedure("static-12", settle_s=0.2, noise_window_s=30.0)
    pv = preview(proc, provisional_dwell_s=5.0)
    eta = RemainingTime(proc, dwell_s=5.0)
    last = pv.windows[-1]
    c = 0.1 * (last.start_s + last.duration_s - sum(w.duration_s for w in pv.windows))  # 0.1·ΣG
    nominal_0 = pv.windows[0].start_s  # the time before the first window
    eta.window_done(0, 10.0 * nominal_0 + pv.windows[0].duration_s, pv.windows[0].duration_s)
    assert eta.ratio == pytest.approx((10.0 * nominal_0 + c) / (nominal_0 + c))


def test_each_kind_of_window_has_its_own_ratio() -> None:
    """rate-1axis with static approaches on time and rate approaches (stop, move, spin-up) 3
    times their nominal time: each kind's ratio is measured, and the remaining time is the
    rate windows' at 3 times, the static ones' at 1."""
    proc = build_procedure("rate-1axis")
    eta = NoPrior(proc, dwell_s=20.0)
    pv = preview(proc, provisional_dwell_s=20.0)
    ratio = {"rate": 3.0}
    w = 0.0
    actual = []
    for k, win in enumerate(pv.windows):
        gap = win.start_s - (pv.windows[k - 1].start_s + pv.windows[k - 1].duration_s if k else 0.0)
        w += ratio.get(win.kind.value, 1.0) * gap + win.duration_s
        actual.append(w)
    d = next(k for k, win in enumerate(pv.windows) if k > 10 and win.kind.value == "rate")
    for k in range(d + 1):
        eta.window_done(k, actual[k], pv.windows[k].duration_s)
    assert eta.kind_ratio("rate") == pytest.approx(3.0)
    assert eta.kind_ratio("static") == pytest.approx(1.0)
    tail = pv.duration_s - eta.ends_s[-1]
    assert eta.remaining_s(actual[d]) == pytest.approx(actual[-1] - actual[d] + eta.ratio * tail)


def test_an_overrunning_window_keeps_the_rest_of_the_procedure_as_remaining() -> None:
    proc = build_procedure("static-12", settle_s=0.2, noise_window_s=30.0)
    eta = NoPrior(proc, dwell_s=5.0)
    ends, total = eta.ends_s, eta.total_s
    for k in range(5):  # on schedule to window 4
        eta.window_done(k, ends[k], eta.lengths_s[k])
    assert eta.ratio == pytest.approx(1.0, abs=1e-6)
    # far past the projected end while window 5 is recorded: what follows window 5 is left
    assert eta.remaining_s(10 * total) == pytest.approx(total - ends[5])


def test_the_dwell_chosen_replans_and_a_resumed_run_measures_its_own_pace() -> None:
    proc = build_procedure("static-12", settle_s=0.2, noise_window_s=30.0)
    eta = RemainingTime(proc)  # no dwell yet: the preview's provisional one
    assert eta.total_s == pytest.approx(preview(proc).duration_s)
    eta.set_dwell(3.0)
    pv = preview(proc, provisional_dwell_s=3.0)
    assert eta.total_s == pytest.approx(pv.duration_s)
    # resumed at window 5 with 1000 s on the clock; moves twice their nominal time since
    res = NoPrior(proc, first_window=5, start_work_s=1000.0, dwell_s=3.0)
    base = _actual_end(pv, 4, 2.0)
    for k in (5, 6, 7):
        res.window_done(k, 1000.0 + _actual_end(pv, k, 2.0) - base, pv.windows[k].duration_s)
    assert res.ratio == pytest.approx(2.0)
    end = 1000.0 + _actual_end(pv, len(pv.windows) - 1, 2.0) - base + 2.0 * (pv.duration_s - res.ends_s[-1])
    w = 1000.0 + _actual_end(pv, 7, 2.0) - base
    assert res.remaining_s(w) == pytest.approx(end - w)


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


def test_before_the_noise_window_ends_the_dwell_is_the_longest_it_can_choose() -> None:
    # 60 s at 250 Hz: the octave Allan curve ends at 4096 samples, so no dwell above 16.384 s
    proc = build_procedure("oscillation-2axis", noise_window_s=60.0)
    eta = RemainingTime(proc, sample_rate_hz=250.0)
    fixed = preview(build_procedure("oscillation-2axis", dwell_s=4096 / 250, noise_window_s=60.0))
    assert eta.total_s == pytest.approx(fixed.duration_s + 60.0)  # + the noise window itself


def test_the_fraction_done_is_the_place_on_the_schedule_and_never_steps_back() -> None:
    """After window k the fraction is its nominal end over the nominal total, E_k / T (the
    preview's figures); part way to the next window it adds that stretch's share worked at
    the measured pace; a pace re-measured slower at the next window does not move it back."""
    proc = build_procedure("static-12", settle_s=0.2, noise_window_s=30.0)
    pv = preview(proc, provisional_dwell_s=5.0)
    ends = [w.start_s + w.duration_s for w in pv.windows]
    eta = NoPrior(proc, dwell_s=5.0)
    assert eta.done_fraction(0.0) == 0.0
    r = 4.0
    for k in range(4):
        eta.window_done(k, _actual_end(pv, k, r), pv.windows[k].duration_s)
    w3 = _actual_end(pv, 3, r)
    assert eta.done_fraction(w3) == pytest.approx(ends[3] / pv.duration_s)
    stretch_s = pv.windows[4].duration_s + r * (pv.windows[4].start_s - ends[3])  # D_4 + r·G_4
    w = w3 + 0.25 * stretch_s
    assert eta.done_fraction(w) == pytest.approx((ends[3] + 0.25 * (ends[4] - ends[3])) / pv.duration_s)
    assert eta.done_fraction(w3 + 10 * stretch_s) == pytest.approx(ends[4] / pv.duration_s)  # capped
    shown = eta.done_fraction(w3 + 0.9 * stretch_s)
    slow_end = w3 + 3.0 * stretch_s  # window 4 took three times the time foreseen
    eta.window_done(4, slow_end, pv.windows[4].duration_s)
    assert eta.ratio > r
    assert eta.done_fraction(slow_end) == pytest.approx(ends[4] / pv.duration_s)
    assert eta.done_fraction(slow_end) >= shown
    for k in range(5, len(ends)):
        eta.window_done(k, slow_end + k, pv.windows[k].duration_s)
    assert eta.done_fraction(slow_end + len(ends) + 1e6) == pytest.approx(1.0)
