"""Offline runs: timelines, windows and the samples inside them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.sim.offline import (
    DEFAULT_AXES,
    simulate_oscillation,
    simulate_rate_steps,
    simulate_static,
    static12_poses_deg,
)
from drivers.sim.physics import NoiseSpec, SensorPhysics, SensorTruth, TemperatureModel

G = 9.81535
BIAS = np.array([1.5, 1.49, 1.51])
K = np.diag([0.0177, 0.0176, 0.0178]) + 1e-5


def _physics(effects=None, noise=None, **kw) -> SensorPhysics:
    truth = SensorTruth(BIAS, K, "V", effects=effects or {}, noise=noise or NoiseSpec.silent())
    return SensorPhysics(
        truth, DEFAULT_AXES, None, G, seed=2, temperature=TemperatureModel.constant(25.0), **kw
    )


def _angle_diff(a, b):
    """a − b wrapped to [−180, 180) (deg): encoders report wrapped angles."""
    return np.mod(np.asarray(a) - np.asarray(b) + 180.0, 360.0) - 180.0


def _inside(run, seg):
    return (run.t_s >= seg[0]) & (run.t_s <= seg[1])


def test_static_run_windows_hold_each_pose():
    poses = static12_poses_deg()
    run = simulate_static(poses, 5.0, _physics(), 50.0, lead_s=1.0)
    assert [s[2] for s in run.segments] == [f"pos{i:02d}" for i in range(1, 13)]
    assert run.segments[-1][1] <= run.t_s[-1]
    assert all(b[0] > a[1] for a, b in zip(run.segments, run.segments[1:], strict=False))
    for seg, pose in zip(run.segments, poses, strict=True):
        m = _inside(run, seg)
        assert m.sum() == pytest.approx(5.0 * 50.0, abs=1)
        np.testing.assert_allclose(_angle_diff(run.encoder_deg[m], pose), 0.0, atol=1e-9)
        # without noise each window reads exactly bias + K·f of its pose (gravity only)
        m_, i = np.radians(pose[1]), np.radians(pose[2])
        f = G * np.array([math.sin(m_) * math.sin(i), math.sin(m_) * math.cos(i), math.cos(m_)])
        np.testing.assert_allclose(run.raw[m], np.broadcast_to(BIAS + K @ f, (m.sum(), 3)), atol=1e-12)


def test_static_run_wires_pose_error_to_its_windows():
    pairs = np.zeros((12, 2))
    pairs[4] = [0.0, 0.01]
    run = simulate_static(static12_poses_deg(), 2.0, _physics({"pose_error": {"angles_rad": pairs}}), 50.0)
    clean = simulate_static(static12_poses_deg(), 2.0, _physics(), 50.0)
    diff = np.abs(run.raw - clean.raw).max(axis=1)
    for j, seg in enumerate(run.segments):
        assert (diff[_inside(run, seg)].max() > 1e-5) == (j == 4)


def test_rate_steps_turn_the_outer_axis_at_the_commanded_rates():
    rates = (0.0, 90.0, -200.0)
    run = simulate_rate_steps(_physics(), 100.0, rates_deg_s=rates, poses_deg=((90.0, 0.0), (0.0, 0.0)))
    assert len(run.segments) == 6
    for seg in run.segments:
        m = _inside(run, seg)
        unwrapped = np.unwrap(run.encoder_deg[m, 0], period=360.0)
        rate = np.polyfit(run.t_s[m], unwrapped, 1)[0]
        assert rate == pytest.approx(float(seg[2].split("_r")[1]), abs=1e-6)
        middle, inner = (float(x[1:]) for x in seg[2].split("_")[:2])
        np.testing.assert_allclose(run.encoder_deg[m, 1:], np.broadcast_to([middle, inner], (m.sum(), 2)))
    assert run.encoder_deg.min() >= -180.0 and run.encoder_deg.max() < 180.0


def test_rate_steps_refuse_rates_beyond_200_deg_s():
    with pytest.raises(ValueError, match="200"):
        simulate_rate_steps(_physics(), 100.0, rates_deg_s=(250.0,))


def test_oscillation_has_the_design_periods_and_amplitudes():
    run = simulate_oscillation(_physics(), 100.0, duration_s=60.0)
    seg = next(s for s in run.segments if s[2] == "oscillation")
    m = _inside(run, seg)
    t = run.t_s[m] - seg[0]
    middle = np.unwrap(run.encoder_deg[m, 1], period=360.0)
    inner = np.unwrap(run.encoder_deg[m, 2], period=360.0)
    # θ = c + A·cos(2π (t − t0) / T): middle 90° ± 90°, T2 = 12 s, from 1.25 s before the window;
    # inner 55° ± 360°, T1 = 30 s, from the window's start
    np.testing.assert_allclose(
        _angle_diff(middle, 90.0 + 90.0 * np.cos(2 * np.pi * (t + 1.25) / 12.0)), 0.0, atol=1e-9
    )
    inner_expected = 55.0 + 360.0 * np.cos(2 * np.pi * t / 30.0)
    np.testing.assert_allclose(_angle_diff(inner, inner_expected), 0.0, atol=1e-9)
    assert 2 * 30.0 == 5 * 12.0
    with pytest.raises(ValueError, match="whole number"):
        simulate_oscillation(_physics(), 100.0, duration_s=45.0)


def test_oscillation_covers_the_sphere():
    run = simulate_oscillation(_physics(), 20.0, duration_s=60.0)
    f = np.linalg.solve(K, (run.raw - BIAS).T).T / G
    for axis in range(3):
        assert f[:, axis].max() > 0.9 and f[:, axis].min() < -0.9


def test_simulated_run_reports_the_bias_its_windows_saw():
    noise = NoiseSpec(white_m_s2_rt_hz=0.0, bias_instability_m_s2=1e-3, bias_instability_tau_s=500.0)
    run = simulate_static(static12_poses_deg(), 5.0, _physics(noise=noise), 20.0)
    first = run.segments[0]
    m = _inside(run, first)
    # the first window is a z-up pose; its mean minus the ideal reading is the wander there
    wander_first = (run.raw[m] - (BIAS + K @ [0, 0, G])).mean(axis=0)
    np.testing.assert_allclose(wander_first, K @ run.bias_wander_m_s2[m].mean(axis=0), atol=1e-12)
    assert np.abs(run.bias_seen() - BIAS).max() > 0  # the wander is not zero
