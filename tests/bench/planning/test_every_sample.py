"""The every-sample fit's predicted covariance and the design's sampled trajectory."""

from __future__ import annotations

import numpy as np

from bench.planning.evaluation import rotation_deg
from bench.planning.every_sample import every_sample_uncertainty
from bench.planning.information import predicted_uncertainty
from bench.planning.noise import UnitNoise
from bench.planning.search import best_within
from bench.planning.trajectory import angle_trajectory, nuisance_response, rotations, specific_force
from bench.procedures.planned import planned_static
from bench.procedures.preview import preview

G = 9.80665


def test_trajectory_lasts_as_the_preview_and_holds_each_pose() -> None:
    proc = planned_static(dwell_s=3.0, repeats=2)
    t, ang = angle_trajectory(proc, 50.0)
    pv = preview(proc)
    n_moves = len(pv.poses_deg)
    assert abs(t[-1] - pv.duration_s) < 0.02 * (2 * n_moves + 1)
    f = specific_force(ang)
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), G, rtol=1e-12)
    for w in pv.windows:  # in the middle of each window the force is the pose's gravity
        k = round((w.start_s + w.duration_s / 2) * 50.0)
        np.testing.assert_allclose(f[k], rotation_deg(w.pose_deg).T @ [0.0, 0.0, G], atol=1e-9)


def test_white_noise_on_dwells_equals_the_window_fit_of_equal_windows() -> None:
    """Different formulation: with white noise and the force constant within m equal windows,
    the OLS of every sample is the window-mean fit with C = N²/T·I."""
    rng = np.random.default_rng(3)
    dirs = rng.standard_normal((8, 3))
    dirs = G * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    fs, T = 20.0, 5.0
    f = np.repeat(dirs, int(fs * T), axis=0)
    t = np.arange(len(f)) / fs
    noise = UnitNoise.from_ug(250.0)
    got = every_sample_uncertainty(t, f, noise)
    ref = predicted_uncertainty(dirs, noise.white_m_s2_rt_hz**2 / T * np.eye(8))
    np.testing.assert_allclose(got.cov, ref.cov, rtol=1e-9, atol=1e-30)


def test_predicted_sigma_matches_a_sample_level_monte_carlo_with_wander_and_random_walk() -> None:
    """300 seeds of an exact AR(1) wander (τ 30 s, dominant) + random walk + white on a tumble,
    least squares of every sample: the empirical RMS σ(K) is within 12 % of the prediction (the
    sampling error of an RMS over 9 elements × 300 seeds is about 3 %; the 1 s blocks of the
    prediction move it by < 2 %)."""
    noise = UnitNoise(250e-6 * G, 300e-6 * G, 30.0, random_walk_m_s2_rt_s=5e-6 * G)
    fs = 10.0
    t, ang = angle_trajectory(planned_static(dwell_s=2.0, repeats=1), fs)
    f = specific_force(ang)
    pred = every_sample_uncertainty(t, f, noise)
    n, dt = len(t), 1.0 / fs
    rng = np.random.default_rng(7)
    a = np.exp(-dt / noise.wander_tau_s)
    x = np.column_stack([np.ones(n), f])
    pinv = np.linalg.pinv(x)
    errs = []
    for _ in range(300):
        kick = noise.wander_m_s2 * np.sqrt(1 - a * a) * rng.standard_normal((n, 3))
        w = np.empty((n, 3))
        w[0] = noise.wander_m_s2 * rng.standard_normal(3)
        for k in range(1, n):
            w[k] = a * w[k - 1] + kick[k]
        rw = np.cumsum(noise.random_walk_m_s2_rt_s * np.sqrt(dt) * rng.standard_normal((n, 3)), axis=0)
        e = noise.white_m_s2_rt_hz / np.sqrt(dt) * rng.standard_normal((n, 3)) + w + rw
        errs.append((pinv @ e)[1:].T)  # (3, 3) K error: rows = channels
    emp = float(np.sqrt(np.mean(np.square(errs))))
    assert abs(emp / pred.k_rms - 1.0) < 0.12, (emp, pred.k_rms)


def test_every_sample_designs_sit_at_the_bound_where_static_dwells_do_not() -> None:
    """The moves' information: at 3 min the every-sample prediction is within 5 % of the
    white-noise bound of any motion; the window fit's best design is ≥ 15 % above it."""
    noise = UnitNoise.from_ug(250.0, 40.0, 200.0)
    e = best_within(noise, 180.0, fit="every-sample")
    w = best_within(noise, 180.0)
    assert e.fit == "every-sample" and e.k_fraction_of_bound < 1.05
    assert w.k_fraction_of_bound > 1.15


def test_planned_tumble_is_the_planned_tumble_fitted_by_every_sample() -> None:
    from bench.calibration.kind import MOVING_PROCEDURES
    from bench.procedures import build_procedure

    a = build_procedure("planned-tumble", dwell_s=3.0, repeats=2)
    b = planned_static(dwell_s=3.0, repeats=2)
    assert a.name == "planned-tumble" and a.steps == b.steps and a.parameters == b.parameters
    assert a.name in MOVING_PROCEDURES and b.name not in MOVING_PROCEDURES


def test_lever_arm_columns_are_the_acceleration_of_an_off_centre_point() -> None:
    """Different formulation: B(t)·r is the second time difference of the point's base-frame
    position R(t)·r, seen in the sensor frame (Rᵀ), on a planned tumble's trapezoidal moves; the
    tilt columns are the change of f = Rᵀ·g·(δ_y, −δ_x, 1) per radian."""
    fs = 400.0
    _, ang = angle_trajectory(planned_static(dwell_s=1.0, repeats=1), fs)
    ang = ang[: int(40 * fs)]
    resp = nuisance_response(ang, fs)
    R = rotations(ang)
    r = np.array([0.03, -0.02, 0.01])
    p = R @ r
    acc = (p[2:] - 2 * p[1:-1] + p[:-2]) * fs**2
    want = np.einsum("nji,nj->ni", R[1:-1], acc)
    got = resp[1:-1, :, :3] @ r
    moving = np.linalg.norm(want, axis=1) > 1e-3
    assert moving.sum() > 1000  # the moves' centripetal and tangential accelerations, ~0.1 m/s²
    a = np.diff(ang, 2, axis=0) * fs**2  # (n - 2, 3) axis accelerations (deg/s²) at samples 1 … n − 2
    jump = np.abs(np.diff(a, axis=0)).max(axis=1) > 1.0  # a corner of a trapezoid between two samples
    near = np.convolve(np.concatenate([jump, [False]]).astype(float), np.ones(9), mode="same") > 0
    smooth = moving & ~near  # the differences agree away from the corners (within 4 samples)
    assert smooth.sum() > 1000
    np.testing.assert_allclose(got[smooth], want[smooth], atol=2e-3 * np.abs(want).max())
    d = np.array([2e-4, -1e-4])
    f0 = specific_force(ang)
    f1 = np.einsum("nji,j->ni", R, G * np.array([d[1], -d[0], 1.0]))
    np.testing.assert_allclose(resp[:, :, 3:] @ d, f1 - f0, atol=1e-12)


def test_nuisance_columns_give_the_least_squares_covariance_of_the_stacked_channels() -> None:
    """Different formulation: with white noise, the prediction with the lever arm and tilt is
    σ²·(XᵀX)⁻¹ of the three channels' rows stacked into one (3n, 17) design."""
    fs = 10.0
    t, ang = angle_trajectory(planned_static(dwell_s=2.0, repeats=1), fs)
    f = specific_force(ang)
    resp = nuisance_response(ang, fs)
    noise = UnitNoise.from_ug(250.0)
    got = every_sample_uncertainty(t, f, noise, nuisance=resp)
    X = np.zeros((3, len(t), 17))
    for i in range(3):
        X[i, :, i] = 1.0
        X[i, :, 3 + 3 * i : 6 + 3 * i] = f
        X[i, :, 12:] = resp[:, i, :]
    stacked = X.reshape(-1, 17)
    want = noise.white_m_s2_rt_hz**2 * fs * np.linalg.inv(stacked.T @ stacked)
    np.testing.assert_allclose(got.cov, want, rtol=1e-8, atol=1e-30)
    np.testing.assert_allclose(got.nuisance, np.sqrt(np.diag(want))[12:], rtol=1e-8)
    assert got.k_rms > every_sample_uncertainty(t, f, noise).k_rms  # nuisance costs a little
