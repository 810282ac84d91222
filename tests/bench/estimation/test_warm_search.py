"""Warm-started REML searches (``warm_search``, ``noise_reml.fit_noise``) against independent
maximisations: known minima of analytic functions, and ℓ_REML of the dense covariance
maximised over a fine grid and polished by scipy from the grid's best point."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize, minimize_scalar

from bench.estimation.noise_reml import fit_noise
from bench.estimation.slow_noise import NoiseParams, covariance, gls
from bench.estimation.warm_search import line_minimum, memoised, warm_minimum

FLOOR, TOP = -30.0, 12.0


@pytest.mark.parametrize("x0", [-30.0, -2.0, 0.7, 12.0])
def test_box_minimum_of_a_correlated_quadratic(x0: float) -> None:
    # f = (x − c)ᵀ H (x − c): interior minimum c; with c₁ beyond the box the minimum is on the
    # face x₁ = 12, at x₀ = c₀ − H₀₁/H₀₀ (12 − c₁) (the constrained stationary point)
    H = np.array([[2.0, 1.5], [1.5, 2.0]])
    for c, want in (
        (np.array([1.0, -3.0]), np.array([1.0, -3.0])),
        (np.array([1.0, 14.0]), np.array([1.0 - 0.75 * (12.0 - 14.0), 12.0])),
    ):

        def f(u: np.ndarray, c: np.ndarray = c) -> float:
            return float((u - c) @ H @ (u - c))

        val, x = warm_minimum(f, np.full(2, x0), [(FLOOR, TOP)] * 2)
        np.testing.assert_allclose(x, want, atol=5e-3)
        assert val == pytest.approx(float((want - c) @ H @ (want - c)), abs=1e-5)


def test_line_minimum_reaches_a_bound_and_an_interior_minimum() -> None:
    # decreasing all the way to the lower bound −5; a parabola with its vertex at 2.3
    f_lo, a_lo = line_minimum(lambda a: np.exp(a), 1.0, -5.0, 4.0, 0.5, 1e-3)
    assert a_lo == pytest.approx(-5.0, abs=1e-3) and f_lo == pytest.approx(np.exp(-5.0), abs=1e-5)
    f_in, a_in = line_minimum(lambda a: (a - 2.3) ** 2, 2.3**2, -5.0, 4.0, 0.5, 1e-3)
    assert a_in == pytest.approx(2.3, abs=1e-3) and f_in < 1e-6


def _problem(seed: int, tau2_true: float, pose_var: float) -> dict[str, np.ndarray]:
    """12 windows of 3 channels: an 8-column design, own noise V, a wander of T_c = 200 s and
    (with ``pose_var``) a random pose error through J, z drawn from that covariance."""
    rng = np.random.default_rng(seed)
    m = 12
    mid = np.sort(rng.uniform(0.0, 600.0, m))
    V = np.stack([np.diag(rng.uniform(0.5, 1.5, 3)) for _ in range(m)])
    J = rng.normal(size=(m, 3, 2))
    X = rng.normal(size=(3 * m, 8))
    C = covariance(
        V, mid, NoiseParams(tau2=np.full(3, tau2_true), corr_time_s=200.0, pose_var_rad2=pose_var), J
    )
    z = X @ rng.normal(size=8) + np.linalg.cholesky(C) @ rng.normal(size=3 * m)
    return {"X": X, "z": z, "V": V, "mid": mid, "J": J}


def _dense_neg_reml(p: dict[str, np.ndarray], tau2: float, pose_var: float) -> float:
    """−ℓ_REML with the covariance formed densely and factored by numpy/scipy (``gls``'s dense branch)."""
    noise = NoiseParams(tau2=np.full(3, tau2), corr_time_s=200.0, pose_var_rad2=pose_var)
    try:
        return -gls(p["X"], p["z"], covariance(p["V"], p["mid"], noise, p["J"])).loglik_reml
    except ValueError:
        return 1e300


def _scale(p: dict[str, np.ndarray]) -> float:
    return float(np.median(np.diagonal(p["V"], axis1=1, axis2=2)))


@pytest.mark.parametrize(("seed", "tau2_true"), [(1, 2.0), (2, 0.3), (3, 5.0), (4, 0.0)])
def test_warm_and_cold_reml_maximum_equal_a_grid_search(seed: int, tau2_true: float) -> None:
    p = _problem(seed, tau2_true, 0.0)
    s = _scale(p)

    def f(u: float) -> float:
        return _dense_neg_reml(p, 0.0 if u <= FLOOR + 1e-6 else s * float(np.exp(u)), 0.0)

    grid = np.arange(FLOOR, TOP + 1e-9, 0.05)
    vals = np.array([f(u) for u in grid])
    i = int(np.argmin(vals))
    r = minimize_scalar(
        f,
        bounds=(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]),
        method="bounded",
        options={"xatol": 1e-7},
    )
    ref_val = min(float(r.fun), float(vals[i]))
    ref_u = float(r.x) if r.fun <= vals[i] else float(grid[i])
    gain = np.ones(3)  # one common level: a 1-parameter search
    fits = {"cold": fit_noise(p["X"], p["z"], p["V"], p["mid"], channel_gain=gain, corr_times_s=[200.0])}
    for shift in (-3.0, 2.0):
        init = NoiseParams(tau2=np.full(3, s * np.exp(ref_u + shift)), corr_time_s=200.0)
        fits[f"warm{shift:+}"] = fit_noise(
            p["X"],
            p["z"],
            p["V"],
            p["mid"],
            channel_gain=gain,
            corr_times_s=[200.0],
            init=init,
            near_init=True,
        )
    for name, (noise, fit) in fits.items():
        # ℓ at the optimiser's tolerance of the grid's (xtol 1e-3 in log τ²: Δℓ ~ ℓ'' 1e-6)
        assert -fit.loglik_reml == pytest.approx(ref_val, abs=1e-5), name
        assert -fit.loglik_reml >= ref_val - 1e-8, name
        if ref_u > FLOOR + 15.0:  # an interior maximum: the level itself to the tolerance
            assert np.log(noise.tau2[0] / s) == pytest.approx(ref_u, abs=0.02), name


def test_warm_reml_maximum_with_pose_variance_equals_polished_grid() -> None:
    p = _problem(5, 1.0, 1.0)
    s = _scale(p)
    jn = float(np.median(np.sum(p["J"] ** 2, axis=(1, 2))) / 2.0)
    g = s / jn  # fit_noise's scale of the pose variance

    def f(u: np.ndarray) -> float:
        return _dense_neg_reml(p, s * float(np.exp(u[0])), g * float(np.exp(u[1])))

    grid = np.arange(-12.0, 6.0 + 1e-9, 0.5)
    vals = np.array([[f(np.array([a, b])) for b in grid] for a in grid])
    i, j = np.unravel_index(int(np.argmin(vals)), vals.shape)
    r = minimize(
        f, np.array([grid[i], grid[j]]), method="Nelder-Mead", options={"xatol": 1e-7, "fatol": 1e-10}
    )
    assert r.fun <= vals[i, j]
    gain = np.ones(3)
    for init in (
        None,
        NoiseParams(tau2=np.full(3, s * np.exp(r.x[0] - 2.0)), pose_var_rad2=g * np.exp(r.x[1] + 1.5)),
    ):
        noise, fit = fit_noise(
            p["X"],
            p["z"],
            p["V"],
            p["mid"],
            J_pose=p["J"],
            estimate_pose=True,
            channel_gain=gain,
            corr_times_s=[200.0],
            init=init,
            near_init=True,
        )
        assert -fit.loglik_reml == pytest.approx(float(r.fun), abs=1e-4)
        assert -fit.loglik_reml >= float(r.fun) - 1e-8
        got = np.log([noise.tau2[0] / s, noise.pose_var_rad2 / g])
        np.testing.assert_allclose(got, r.x, atol=0.05)


def test_memoised_evaluates_each_distinct_point_once() -> None:
    calls: list[tuple[float, ...]] = []

    def fun(x: np.ndarray) -> float:
        calls.append(tuple(x))
        return float(np.sum(x**2))

    f = memoised(fun)
    pts = [np.array([1.0, 2.0]), np.array([1.0, 2.0]), np.array([1.0, 2.0 + 1e-15]), np.array([0.0, 0.0])]
    values = [f(p) for p in pts]
    assert calls == [(1.0, 2.0), (1.0, 2.0 + 1e-15), (0.0, 0.0)]
    assert values == [5.0, 5.0, 1.0 + (2.0 + 1e-15) ** 2, 0.0]
