"""Motion profiles against closed forms and against numerical differentiation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.sim.motion import (
    AxisProfile,
    ConstantRate,
    Hold,
    Oscillation,
    TableProfile,
    TrapezoidMove,
    end_state,
)


def _check_derivatives(seg, t_max: float) -> None:
    """Rate and acceleration agree with central differences of the angle."""
    t = np.linspace(1e-3, t_max - 1e-3, 2001)
    h = 1e-6
    a_p, _, _ = seg.evaluate(t + h)
    a_m, _, _ = seg.evaluate(t - h)
    _, r, acc = seg.evaluate(t)
    np.testing.assert_allclose(r, (a_p - a_m) / (2 * h), atol=1e-6)
    _, r_p, _ = seg.evaluate(t + h)
    _, r_m, _ = seg.evaluate(t - h)
    d_rate = (r_p - r_m) / (2 * h)
    # acceleration is piecewise constant: compare away from the switching instants
    smooth = np.abs(d_rate - acc) < 1e-3
    assert smooth.mean() > 0.99


def test_trapezoid_reaches_rate_and_takes_closed_form_time():
    move = TrapezoidMove(0.0, math.radians(90), math.radians(20), math.radians(40))
    # v²/a = 10° < 90°: trapezoid, 2·0.5 s + (90 − 10)/20 s = 5 s
    assert move.duration_s == pytest.approx(5.0)
    angle, rate, accel = move.evaluate(np.array([0.25, 2.0, 4.75, 5.0, 7.0]))
    np.testing.assert_allclose(np.degrees(rate), [10.0, 20.0, 10.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(np.degrees(accel), [40.0, 0.0, -40.0, 0.0, 0.0], atol=1e-12)
    # 0.5·40·0.25² = 1.25°; at 2 s: 5° + 20·1.5 = 35°
    np.testing.assert_allclose(np.degrees(angle[:2]), [1.25, 35.0], atol=1e-12)
    np.testing.assert_allclose(np.degrees(angle[3:]), [90.0, 90.0], atol=1e-12)
    _check_derivatives(move, move.duration_s)


def test_short_move_is_triangular_and_negative_moves_mirror():
    move = TrapezoidMove(math.radians(10), math.radians(5), math.radians(20), math.radians(40))
    # D = 5° < 10°: peak √(5·40) = √200 °/s, duration 2·√(5/40) s
    assert move.duration_s == pytest.approx(2 * math.sqrt(5 / 40))
    t_peak = move.duration_s / 2
    _, rate, _ = move.evaluate(np.array([t_peak]))
    assert np.degrees(rate[0]) == pytest.approx(-math.sqrt(200.0))
    assert math.degrees(end_state(move)[0]) == pytest.approx(5.0)
    _check_derivatives(move, move.duration_s)


def test_zero_length_move_lasts_zero():
    move = TrapezoidMove(1.0, 1.0, 1.0, 1.0)
    assert move.duration_s == 0.0
    assert end_state(move) == (1.0, 0.0)


def test_constant_rate_ramp_and_angle():
    seg = ConstantRate(0.0, math.radians(200), math.radians(100), duration_s=10.0)
    assert seg.ramp_s == pytest.approx(2.0)
    angle, rate, accel = seg.evaluate(np.array([1.0, 2.0, 6.0]))
    np.testing.assert_allclose(np.degrees(rate), [100.0, 200.0, 200.0])
    np.testing.assert_allclose(np.degrees(accel), [100.0, 0.0, 0.0])
    # ½·100·1² = 50°, ½·100·4 = 200°, 200 + 200·4 = 1000°
    np.testing.assert_allclose(np.degrees(angle), [50.0, 200.0, 1000.0])
    _check_derivatives(seg, 10.0)
    stop = ConstantRate(angle[-1], 0.0, math.radians(100), 3.0, initial_rate_rad_s=math.radians(200))
    assert stop.rest_from_s == pytest.approx(2.0)
    a_end, r_end = end_state(stop)
    assert r_end == 0.0
    assert math.degrees(a_end) == pytest.approx(1000.0 + 200.0)


def test_constant_rate_too_short_is_rejected():
    with pytest.raises(ValueError, match="shorter than the ramp"):
        ConstantRate(0.0, 1.0, 0.5, duration_s=1.0)


def test_oscillation_closed_form():
    seg = Oscillation(0.1, math.radians(90), 12.0, 24.0, phase_rad=0.3)
    t = np.linspace(0, 24, 97)
    omega = 2 * math.pi / 12
    angle, _rate, accel = seg.evaluate(t)
    np.testing.assert_allclose(angle, 0.1 + math.radians(90) * np.sin(omega * t + 0.3))
    np.testing.assert_allclose(accel, -(omega**2) * (angle - 0.1), atol=1e-12)
    _check_derivatives(seg, 24.0)


def test_profile_joins_segments_and_tracks_rest():
    a = math.radians(30)
    axis = AxisProfile(
        (Hold(0.0, 2.0), TrapezoidMove(0.0, a, math.radians(30), math.radians(60)), Hold(a, 5.0)),
        start_s=1.0,
    )
    move_end = 1.0 + 2.0 + axis.segments[1].duration_s
    t = np.array([0.0, 2.0, 3.5, move_end + 0.5, move_end + 4.0, move_end + 100.0])
    angle, rate, _, since_rest = axis.evaluate(t)
    assert angle[0] == 0.0 and angle[1] == 0.0
    assert np.isinf(since_rest[:3]).all()  # never moved, then moving
    np.testing.assert_allclose(since_rest[3:], [0.5, 4.0, 100.0])
    np.testing.assert_allclose(angle[3:], a)
    assert rate[2] > 0


def test_profile_rejects_a_jump():
    with pytest.raises(ValueError, match="segment 1 starts"):
        AxisProfile((Hold(0.0, 1.0), Hold(0.5, 1.0)))


def test_nonfinite_parameters_are_rejected():
    with pytest.raises(ValueError, match="angle_rad must be finite"):
        Hold(float("nan"), 1.0)


def test_table_profile_shapes():
    prof = TableProfile(
        (
            AxisProfile((ConstantRate(0.0, 1.0, 2.0, 5.0),)),
            AxisProfile((Oscillation(0.0, 0.5, 4.0, 5.0),)),
            AxisProfile((Hold(0.2, 5.0),)),
        )
    )
    kin = prof.kinematics(np.linspace(0, 5, 11))
    assert kin.angles_rad.shape == (11, 3)
    assert kin.since_rest_s is not None and kin.since_rest_s.shape == (11, 3)
    np.testing.assert_allclose(kin.angles_rad[:, 2], 0.2)
    assert prof.end_s == 5.0
