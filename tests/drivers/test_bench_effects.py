"""Bench physics beyond the catalogue in the truth model (drivers/sim/bench_effects.py)."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.sim.bench_effects import error_axes, lagged, last_direction, true_axes
from drivers.sim.offline import DEFAULT_AXES, simulate_oscillation, simulate_static, static12_poses_deg
from drivers.sim.physics import NoiseSpec, SensorPhysics, SensorTruth


def _quiet(effects: dict) -> SensorTruth:
    t = SensorTruth.typical("m/s2", seed=3).with_noise(NoiseSpec(white_m_s2_rt_hz=0.0))
    return t.with_effects(effects)


def test_axis_error_turns_the_axis_about_the_two_perpendicular_directions() -> None:
    for u in np.eye(3):
        e1, e2 = error_axes(u)
        assert abs(e1 @ u) < 1e-15 and abs(e2 @ u) < 1e-15 and abs(e1 @ e2) < 1e-15
    ang = np.array([[0.0, 0.0], [0.0, 1e-3], [0.0, 0.0]])
    axes = true_axes(DEFAULT_AXES, ang)
    # middle axis x turned by b about e2 = x × z = -y: towards +z, off perpendicular to the outer z
    assert np.allclose(axes[1], [np.cos(1e-3), 0.0, np.sin(1e-3)], atol=1e-15)
    assert np.allclose(axes[[0, 2]], DEFAULT_AXES[[0, 2]])
    with pytest.raises(ValueError, match="one pair per table axis"):
        true_axes(DEFAULT_AXES, np.zeros((2, 2)))


def test_middle_axis_off_perpendicular_moves_gravity_as_its_geometry_says() -> None:
    """Pose (0, 90, 0): the middle axis x turned 1 mrad towards z tilts the unit's z axis, after
    the 90° turn about x, by 1 mrad towards x: f_x = g·sin(1e-3) by hand."""
    b = 1e-3
    t = _quiet({"table_axis_error": {"angles_rad": [[0.0, 0.0], [0.0, b], [0.0, 0.0]]}})
    phy = SensorPhysics(t, DEFAULT_AXES, seed=1)
    run = simulate_static(np.array([[0.0, 90.0, 0.0], [0.0, 0.0, 0.0]]), 2.0, phy, 50.0)
    a, e, _ = run.segments[0]
    sl = (run.t_s >= a) & (run.t_s <= e)
    f = np.linalg.solve(t.K, run.raw[sl].mean(axis=0) - t.bias)
    assert abs(f[0]) == pytest.approx(phy.g_local_m_s2 * np.sin(b), rel=1e-3)


def test_periodic_line_and_angle_harmonic_add_their_sines() -> None:
    spec = {"frequency_hz": 7.0, "amplitude_m_s2": [0.0, 0.01, 0.0], "phase_rad": 0.3}
    t0, t1 = _quiet({}), _quiet({"periodic_line": spec})
    run0 = simulate_static(static12_poses_deg()[:2], 3.0, SensorPhysics(t0, DEFAULT_AXES, seed=2), 100.0)
    run1 = simulate_static(static12_poses_deg()[:2], 3.0, SensorPhysics(t1, DEFAULT_AXES, seed=2), 100.0)
    d = np.linalg.solve(t1.K, (run1.raw - run0.raw).T).T
    assert np.allclose(d[:, 1], 0.01 * np.sin(2 * np.pi * 7.0 * run1.t_s + 0.3), atol=1e-9)
    h = {"axis": 3, "harmonic": 2, "amplitude_m_s2": [0.02, 0.0, 0.0], "phase_rad": 0.0}
    t2 = _quiet({"angle_harmonic": h})
    o0 = simulate_oscillation(SensorPhysics(t0, DEFAULT_AXES, seed=2), 100.0, duration_s=30.0)
    o2 = simulate_oscillation(SensorPhysics(t2, DEFAULT_AXES, seed=2), 100.0, duration_s=30.0)
    d2 = np.linalg.solve(t2.K, (o2.raw - o0.raw).T).T
    assert np.allclose(d2[:, 0], 0.02 * np.sin(2 * np.deg2rad(o2.encoder_deg[:, 2])), atol=1e-9)
    with pytest.raises(ValueError, match="axis must be an integer from 1 to 3"):
        SensorPhysics(_quiet({"angle_harmonic": {**h, "axis": 4}}), DEFAULT_AXES)


def test_clock_drift_is_a_delay_that_grows_from_zero() -> None:
    """At time t a drift ρ is the time skew ρ·t: compare with a time_skew run at one sample."""
    rho = 1e-4
    o1 = simulate_oscillation(
        SensorPhysics(_quiet({"clock_drift": {"delay_s_per_s": rho}}), DEFAULT_AXES), 100.0, duration_s=60.0
    )
    i = 5000
    tk = float(o1.t_s[i])
    o2 = simulate_oscillation(
        SensorPhysics(_quiet({"time_skew": {"delay_s": rho * tk}}), DEFAULT_AXES), 100.0, duration_s=60.0
    )
    assert np.allclose(o1.raw[i], o2.raw[i], rtol=0, atol=1e-12)
    assert not np.allclose(o1.raw[i + 1000], o2.raw[i + 1000], rtol=0, atol=1e-9)


def test_last_direction_and_thermal_lag_by_hand() -> None:
    r = np.array([0.0, 0.0, 1.0, 2.0, 0.0, 0.0, -1.0, 0.0])
    assert last_direction(r, 0.0).tolist() == [0, 0, 1, 1, 1, 1, -1, -1]
    assert last_direction(r[:2], -1.0).tolist() == [-1, -1]
    t = np.arange(0.0, 100.0, 0.5)
    temp = np.where(t >= 10.0, 1.0, 0.0)
    out = lagged(t, temp, 20.0, None)
    # the step's value holds over the interval before its first sample (from 9.5 s): the
    # response is 1 − exp(−(t − 9.5)/τ) at and after it, 0 before
    assert np.allclose(out[t >= 10.0], 1.0 - np.exp(-(t[t >= 10.0] - 9.5) / 20.0), atol=1e-12)
    assert np.all(out[t < 10.0] == 0.0)
