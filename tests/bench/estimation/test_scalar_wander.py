"""Orientation-free fit on long sessions: the windows' shared wander reaches the sigmas."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.estimation.scalar_fit import fit_scalar
from bench.estimation.scalar_wander import _quadratic, scalar_wander
from benchmarks.study_long_recording import LongSession, simulate

G = 9.80665


def test_banded_quadratic_and_logdet_match_the_dense_covariance() -> None:
    rng = np.random.default_rng(0)
    m = 15
    b = rng.uniform(1, 2, m)
    n = rng.normal(size=(m, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    t = np.sort(rng.uniform(0, 100, m))
    Y = rng.normal(size=(m, 4))
    C = np.diag(b) + 0.7 * (n @ n.T) * np.exp(-np.abs(t[:, None] - t[None]) / 20.0)  # written out
    Q, logdet = _quadratic(Y, b, n, t, 0.7, 20.0)
    np.testing.assert_allclose(Q, Y.T @ np.linalg.solve(C, Y), rtol=1e-10, atol=1e-12)
    assert abs(logdet - np.linalg.slogdet(C)[1]) < 1e-9


def test_long_hand_held_sessions_z_spread() -> None:
    """10 orientation-free sessions of 240 windows over 20 h (1 h wander, ±5 °C daily,
    0.003 rad placement): z of b and L (L Lᵀ = K Kᵀ) against the truth spread 0.75–1.25
    with the wander (measured 0.89 on 6 sessions), more without it (1.22)."""
    cfg = replace(LongSession(), m=240)
    z_w, z_i = [], []
    for seed in range(10):
        r = simulate(cfg, seed)
        sf = fit_scalar(r["y"], r["V"], G)
        sw = scalar_wander(sf, r["y"], G, r["mid_s"])
        L = np.linalg.cholesky(r["K"] @ r["K"].T)
        err = np.concatenate([sf.bias - r["b"], (sf.L - L)[np.tril_indices(3)]])
        z_i.append(err / sf.sigma)
        z_w.append(err / (sf.sigma if sw is None else np.sqrt(np.diag(sw.cov))))
    assert 0.75 <= float(np.std(z_w)) <= 1.25, np.std(z_w)
    assert float(np.std(z_w)) < float(np.std(z_i))
    assert float(np.max(np.abs(z_w))) < 4.0


def test_short_session_is_left_alone() -> None:
    r = simulate(replace(LongSession(), m=12, hours=0.1), 1)
    sf = fit_scalar(r["y"], r["V"], G)
    assert scalar_wander(sf, r["y"], G, r["mid_s"]) is None
