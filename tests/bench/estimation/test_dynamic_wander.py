"""Block wander of a long-pose design: REML level and the covariance it adds, against Monte Carlo.

A linear stand-in for a rate-table run: six poses (each axis up, then down), 240 s each at
5 Hz, raw = b + K f + s(t) + white, s a Gauss–Markov wander (level τ, 200 s) shared in shape by
the channels. The WLS fit of b and K (the dynamic fit's estimator with white weights) is
scored against the truth with (a) the white covariance only and (b) white + the block
wander's covariance.
"""

from __future__ import annotations

import math

import numpy as np

from bench.estimation.dynamic_wander import fit_block_wander

FS, POSE_S, TC_S, TAU, WHITE = 5.0, 240.0, 200.0, 4e-4, 2e-3
UPS = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], dtype=float) * 9.8


def _run(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(z-scores of K with white cov, with white + wander cov, REML wander level (3,), z of the
    bias against the run's mean with white + ``cov_run_mean``, the same with ``cov``)."""
    rng = np.random.default_rng(seed)
    n_pose = int(POSE_S * FS)
    f = np.repeat(UPS, n_pose, axis=0)
    n = f.shape[0]
    t = np.arange(n) / FS
    K = np.eye(3) + 1e-3 * rng.standard_normal((3, 3))
    b = 0.1 * rng.standard_normal(3)
    a = math.exp(-1.0 / (FS * TC_S))
    s = np.empty((n, 3))
    s[0] = TAU * rng.standard_normal(3)
    w = TAU * math.sqrt(1 - a * a) * rng.standard_normal((n, 3))
    for i in range(1, n):
        s[i] = a * s[i - 1] + w[i]
    y = b + f @ K.T + s + WHITE * rng.standard_normal((n, 3))
    # per channel c the regressors [1, f]; θ = (b, K row-major): J_t[c] (3, 12)
    J = np.zeros((n, 3, 12))
    for c in range(3):
        J[:, c, c] = 1.0
        J[:, c, 3 + 3 * c : 6 + 3 * c] = f
    sig = np.full(3, WHITE)
    H = np.einsum("ncp,ncq->pq", J, J) / WHITE**2
    theta = np.linalg.solve(H, np.einsum("ncp,nc->p", J, y) / WHITE**2)
    e = y - np.einsum("ncp,p->nc", J, theta)
    blk = np.floor(t / (t[-1] / 199.0)).astype(int)
    nb = blk[-1] + 1
    j_sum = np.zeros((nb, 3, 12))
    e_sum = np.zeros((nb, 3))
    counts = np.zeros(nb)
    np.add.at(j_sum, blk, J)
    np.add.at(e_sum, blk, e)
    np.add.at(counts, blk, 1.0)
    mid = (np.arange(nb) + 0.5) * (t[-1] / 199.0)
    h_inv = np.linalg.inv(H)
    bw = fit_block_wander(j_sum, e_sum, counts, mid, sig, h_inv, channel_gain=np.ones(3))
    assert bw is not None
    err = (theta - np.r_[b, K.ravel()])[3:]
    z_white = err / np.sqrt(np.diag(h_inv))[3:]
    z_model = err / np.sqrt(np.diag(h_inv + bw.cov))[3:]
    err_run = theta[:3] - (b + s.mean(axis=0))  # every sample weighs alike: the run's mean
    z_run = err_run / np.sqrt(np.diag(h_inv + bw.cov_run_mean))[:3]
    z_run_long_cov = err_run / np.sqrt(np.diag(h_inv + bw.cov))[:3]
    return z_white, z_model, np.sqrt(bw.noise.tau2), z_run, z_run_long_cov


def test_block_wander_makes_k_sigmas_honest() -> None:
    """16 seeds × 9 K elements: RMS z with the wander 0.75–1.3 (N(0,1): ±0.15 at 2σ for
    ~40 effectively independent values); with the white covariance alone above 2; the
    REML level within a factor 2 of the truth in the median."""
    zw, zm, lvl, _, _ = zip(*(_run(s) for s in range(16)), strict=True)
    rms_w = float(np.sqrt(np.mean(np.square(zw))))
    rms_m = float(np.sqrt(np.mean(np.square(zm))))
    assert rms_w > 2.0, rms_w
    assert 0.75 < rms_m < 1.3, rms_m
    assert 0.5 * TAU < float(np.median(lvl)) < 2.0 * TAU


def test_run_mean_covariance_covers_the_run_mean_bias_and_no_more() -> None:
    """The bias against the run's mean: with ``cov_run_mean`` its RMS z over 16 seeds × 3
    channels is 0.7–1.35 (N(0,1): about ±0.2 at 2σ for 48 values); the long-run ``cov`` holds
    the wander's own average over the run (≈ 2τ²T_c/T ≫ the white share here), so against the
    run's mean it over-covers (RMS < 0.6)."""
    out = [_run(s) for s in range(16)]
    rms_run = float(np.sqrt(np.mean(np.square([o[3] for o in out]))))
    rms_long_cov = float(np.sqrt(np.mean(np.square([o[4] for o in out]))))
    assert 0.7 < rms_run < 1.35, rms_run
    assert rms_long_cov < 0.6, rms_long_cov
