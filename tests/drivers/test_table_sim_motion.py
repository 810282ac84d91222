"""The simulated controller's TRUE kinematics, settling and faults (hand-driven clock)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.base import AxisMode
from drivers.sim.table_axis import AxisLimits, Ringing
from drivers.sim.table_controller import TableController
from drivers.sim.table_segments import RingDown
from drivers.table_protocol import Interlock, Status

from .table_fakes import ManualClock


def make(clock: ManualClock, **kw: object) -> TableController:
    ctl = TableController(clock, **kw)  # type: ignore[arg-type]
    ctl.interlock_close(None)
    return ctl


def integrate(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Cumulative trapezoid integral of y over t."""
    return np.concatenate(([0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))))


def test_kinematics_is_self_consistent_over_mixed_motion() -> None:
    """angle = ∫rate and rate = ∫accel across moves, ringing, rate ramps and oscillation."""
    clock = ManualClock()
    ctl = make(clock, ringing=Ringing(0.2, 3.0, 0.4))
    ctl.set_mode(1, AxisMode.POSITION)
    ctl.set_mode(2, AxisMode.RATE)
    ctl.set_mode(3, AxisMode.OSCILLATION)
    ctl.demand_position(1, 120.0)
    ctl.demand_rate(2, 30.0)
    ctl.demand_oscillation(3, 5.0, 0.5, 0.0)
    clock.advance(0.7)
    ctl.demand_position(1, -60.0)  # replanned mid-move
    clock.advance(5.0)
    ctl.stop(2)
    clock.advance(3.0)
    t = np.linspace(0.0, clock.t, 80001)
    k = ctl.kinematics(t)
    assert k.angles_rad.shape == (t.size, 3)
    for j in range(3):
        ang, rate, acc = k.angles_rad[:, j], k.rates_rad_s[:, j], k.accels_rad_s2[:, j]
        np.testing.assert_allclose(ang - ang[0], integrate(rate, t), atol=2e-6)
        # accel jumps between samples: each costs up to |jump|·dt/2 ≈ 5e-4 rad/s of trapezoid error
        np.testing.assert_allclose(rate - rate[0], integrate(acc, t), atol=3e-3)
    assert np.max(np.abs(k.rates_rad_s[:, 0])) <= math.radians(200.0) + 1e-9
    assert np.max(np.abs(k.accels_rad_s2[:, 1])) <= math.radians(200.0) + 1e-9


def test_axis_order_is_outermost_first_and_angles_unwrapped() -> None:
    clock = ManualClock()
    ctl = make(clock)
    ctl.set_mode(1, AxisMode.RATE)
    ctl.demand_rate(1, 100.0)
    clock.advance(10.0)
    k = ctl.kinematics(np.array([clock.t]))
    # 100 deg/s for 10 s less the ramp's lag 100²/(2·200) = 25 deg -> 975 deg, unwrapped
    assert math.degrees(k.angles_rad[0, 0]) == pytest.approx(975.0)
    assert k.angles_rad[0, 1:].tolist() == [0.0, 0.0]
    assert ctl.read(1)[0] == pytest.approx(975.0 - 1080.0)  # readout wrapped to [-180, 180)


def test_in_position_waits_for_the_settle_time() -> None:
    clock = ManualClock()
    ctl = make(clock, limits=AxisLimits(rate_deg_s=10.0, acc_deg_s2=20.0, settle_s=1.5))
    ctl.set_mode(3, AxisMode.POSITION)
    ctl.demand_position(3, 30.0)
    move_s = 10.0 / 20.0 + 30.0 / 10.0  # trapezoid: 2·v/a + (D − v²/a)/v = 3.5 s
    clock.advance(move_s - 1e-6)
    assert Status.MOVING in ctl.status(3)
    clock.advance(2e-6 + 1.5 - 1e-3)
    assert ctl.status(3) == Status.INTERLOCK_CLOSED
    clock.advance(2e-3)
    assert Status.IN_POSITION in ctl.status(3)


def test_slow_settle_rings_and_delays_in_position() -> None:
    clock = ManualClock()
    ctl = make(clock)
    ctl.inject("slow_settle", peak_deg=0.05, frequency_hz=2.0, decay_s=1.0)
    ctl.set_mode(1, AxisMode.POSITION)
    ctl.demand_position(1, 90.0)
    move_s = 2 * math.sqrt(90 / 200)
    ring = RingDown(math.radians(90), math.radians(0.05), 2.0, 1.0, math.radians(0.001))
    settled_s = ring.settled_after_s()
    # independent check of the settle time: x·e^(1−x) = 0.001/0.05 has its root x > 1 near 5.75
    x = settled_s / 1.0
    assert x * math.exp(1 - x) == pytest.approx(0.02, rel=1e-6)
    t = move_s + np.linspace(0.0, 6.0, 6001)
    dev = np.degrees(ctl.kinematics(t).angles_rad[:, 0]) - 90.0
    assert np.max(np.abs(dev)) == pytest.approx(
        0.05, rel=0.1
    )  # sin(Ωτ) does not quite reach the envelope peak
    assert np.all(np.abs(dev[t - move_s > settled_s]) < 0.001)
    clock.advance(move_s + settled_s + 0.5 - 1e-3)
    assert Status.IN_POSITION not in ctl.status(1)
    clock.advance(2e-3)
    assert Status.IN_POSITION in ctl.status(1)


def test_interlock_trip_mid_move_brakes_and_faults() -> None:
    clock = ManualClock()
    ctl = make(clock)
    ctl.set_mode(2, AxisMode.RATE)
    ctl.demand_rate(2, 50.0)
    ctl.inject("interlock_trip", after_s=2.0)
    clock.advance(2.1)
    assert ctl.interlock_state(2) is Interlock.FAULT
    assert ctl.mode(2) is AxisMode.OFF
    assert ctl.read(2)[1] == pytest.approx(50.0 - 200.0 * 0.1)  # braking at the absolute 200 deg/s²
    k = ctl.kinematics(np.array([1.9, 2.0 + 0.25, 3.0]))
    assert np.degrees(k.rates_rad_s[:, 1]) == pytest.approx([50.0, 0.0, 0.0])
    codes = [ctl.pop_error() for _ in range(4)]
    assert [(e.code, e.axis) for e in codes if e] == [(9, 1), (9, 2), (9, 3)]
    with pytest.raises(Exception, match="reset first"):
        ctl.interlock_close(2)
    ctl.interlock_reset(2)
    ctl.interlock_close(2)
    assert ctl.interlock_state(2) is Interlock.CLOSED


def test_stalled_axis_does_not_move_then_trips_following_error() -> None:
    clock = ManualClock()
    ctl = make(clock)
    ctl.set_mode(3, AxisMode.POSITION)
    ctl.inject("stalled_axis", axis=3, trip_s=0.5)
    ctl.demand_position(3, 10.0)
    move_s = 2 * math.sqrt(10 / 200)
    clock.advance(move_s + 0.4)
    assert ctl.read(3)[0] == 0.0
    assert Status.IN_POSITION not in ctl.status(3)
    clock.advance(0.2)
    assert Status.FOLLOWING_ERROR in ctl.status(3)
    assert ctl.mode(3) is AxisMode.OFF
    err = ctl.pop_error()
    assert err is not None and (err.code, err.axis) == (3, 3)
    ctl.clear("stalled_axis")
    ctl.interlock_reset(3)
    assert Status.FOLLOWING_ERROR not in ctl.status(3)


def test_history_is_bounded_and_old_times_are_refused() -> None:
    clock = ManualClock()
    ctl = make(clock, history_s=60.0)
    ctl.set_mode(1, AxisMode.POSITION)
    for i in range(30):
        ctl.demand_position(1, float(i % 2) * 10.0)
        clock.advance(5.0)
    k = ctl.kinematics(np.linspace(clock.t - 50.0, clock.t, 1000))
    assert np.all(np.isfinite(k.angles_rad))
    with pytest.raises(ValueError, match="older than the retained history"):
        ctl.kinematics(np.array([1.0]))
    with pytest.raises(ValueError, match="finite"):
        ctl.kinematics(np.array([clock.t, math.nan]))


@pytest.mark.parametrize(
    ("fault", "params", "match"),
    [
        ("melted", {}, "unknown fault"),
        ("stalled_axis", {}, "missing"),
        ("stalled_axis", {"axis": 4}, "axis"),
        ("garbled", {"probability": 2.0}, "probability"),
        ("interlock_trip", {"after": 1.0}, "unknown parameter"),
        ("slow_settle", {"decay_s": math.inf}, "finite"),
    ],
)
def test_bad_fault_injection_is_refused(fault: str, params: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make(ManualClock()).inject(fault, **params)
