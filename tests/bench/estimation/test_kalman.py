"""Kalman filter and RTS smoother against batch least squares (a different formulation)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.estimation.kalman import KalmanState, predict, rts_smooth, update, update_diagonal


def test_joseph_update_equals_information_form() -> None:
    rng = np.random.default_rng(0)
    A = rng.standard_normal((4, 4))
    s = KalmanState(rng.standard_normal(4), A @ A.T + np.eye(4))
    H = rng.standard_normal((7, 4))
    r = rng.uniform(0.5, 2.0, 7)
    z = rng.standard_normal(7)
    a = update(s, z, H @ s.x, H, np.diag(r))
    b = update_diagonal(s, z, H @ s.x, H, r)
    np.testing.assert_allclose(a.x, b.x, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(a.P, b.P, rtol=1e-10, atol=1e-12)


def test_static_state_filter_equals_weighted_least_squares() -> None:
    """Constant state, Gaussian prior: the filter's last state is the regularised WLS solution."""
    rng = np.random.default_rng(1)
    x_true = np.array([1.0, -2.0, 0.5])
    H = rng.standard_normal((200, 3))
    sig = 0.3
    z = H @ x_true + sig * rng.standard_normal(200)
    P0 = np.eye(3) * 100.0
    s = KalmanState(np.zeros(3), P0)
    for k in range(0, 200, 10):
        s = update(predict(s), z[k : k + 10], H[k : k + 10] @ s.x, H[k : k + 10], sig**2 * np.eye(10))
    info = np.linalg.inv(P0) + H.T @ H / sig**2
    x_ls = np.linalg.solve(info, H.T @ z / sig**2)
    np.testing.assert_allclose(s.x, x_ls, rtol=1e-9)
    np.testing.assert_allclose(s.P, np.linalg.inv(info), rtol=1e-9)


def test_rts_smoother_equals_full_trajectory_least_squares() -> None:
    """Random walk x_k observed in noise: RTS means = the batch solution over all x_0..x_N-1."""
    rng = np.random.default_rng(2)
    n, q, r, p0 = 40, 0.05, 0.4, 4.0
    x = np.cumsum(np.sqrt(q) * rng.standard_normal(n)) + 1.0
    z = x + np.sqrt(r) * rng.standard_normal(n)
    filt, pred = [], []
    s = KalmanState(np.zeros(1), np.array([[p0]]))
    for k in range(n):
        pk = s if k == 0 else predict(s, None, np.array([[q]]))
        s = update(pk, z[k : k + 1], pk.x, np.ones((1, 1)), np.array([[r]]))
        pred.append(pk)
        filt.append(s)
    sm = rts_smooth(filt, pred)
    # batch: minimise x0²/p0 + Σ (x_k − x_{k−1})²/q + Σ (z_k − x_k)²/r
    A = np.diag(np.full(n, 1.0 / r))
    A[0, 0] += 1.0 / p0
    D = (np.eye(n) - np.eye(n, k=-1))[1:]
    A += D.T @ D / q
    x_batch = np.linalg.solve(A, z / r)
    np.testing.assert_allclose([s.x[0] for s in sm], x_batch, rtol=1e-9, atol=1e-12)
    cov = np.linalg.inv(A)
    np.testing.assert_allclose([s.P[0, 0] for s in sm], np.diag(cov), rtol=1e-9)
    assert all(a.P[0, 0] <= b.P[0, 0] + 1e-15 for a, b in zip(sm, filt, strict=True))


def test_bad_state_rejected() -> None:
    with pytest.raises(ValueError, match="P has shape"):
        KalmanState(np.zeros(2), np.eye(3))
    with pytest.raises(ValueError, match="finite"):
        KalmanState(np.array([np.nan]), np.eye(1))
