"""The static fit's bias sigma against the run's mean bias with a wander shared by the windows
(``static_wander.run_mean_bias_cov``), checked against the errors of the GLS estimate drawn."""

from __future__ import annotations

import numpy as np

from bench.estimation.slow_noise import NoiseParams, covariance
from bench.estimation.static_design import design_rows
from bench.estimation.static_wander import _exp_row_sums, run_mean_bias_cov


def _session(rng: np.random.Generator, m: int) -> tuple[np.ndarray, ...]:
    """Directions, window covariances and irregular window times of one session."""
    u = rng.standard_normal((m, 3))
    f = 9.81 * u / np.linalg.norm(u, axis=1, keepdims=True)
    V = np.einsum("w,ij->wij", rng.uniform(0.5, 2.0, m), np.diag([1.0, 1.5, 0.8]))
    mid = np.cumsum(rng.uniform(40.0, 90.0, m))
    return f, V, mid


def test_exp_row_sums_are_the_dense_sums() -> None:
    rng = np.random.default_rng(1)
    t = rng.permutation(np.cumsum(rng.uniform(1.0, 50.0, 40)))
    dense = np.exp(-np.abs(t[:, None] - t[None, :]) / 70.0).sum(axis=1)
    np.testing.assert_allclose(_exp_row_sums(t, 70.0), dense, rtol=1e-12)


def test_run_mean_bias_cov_is_the_spread_of_drawn_errors_about_the_windows_mean_wander() -> None:
    """20 000 sessions of 14 windows: wander s_c(t_w) drawn from its exponential correlation,
    each window's own noise from V; the GLS bias minus b + mean_w s(t_w) has the covariance the
    formula states (each variance to 1 % sampling error; 5 of them allowed), while the fit's C
    (against the long-run bias) is far above it."""
    rng = np.random.default_rng(7)
    m, n = 14, 20000
    f, V, mid = _session(rng, m)
    noise = NoiseParams(tau2=np.array([4.0, 2.0, 9.0]), corr_time_s=200.0)
    Sigma = covariance(V, mid, noise)
    H = design_rows(f).reshape(3 * m, 12)
    Si_H = np.linalg.solve(Sigma, H)
    C = np.linalg.inv(H.T @ Si_H)
    A = C @ Si_H.T  # (12, 3m)

    P = np.exp(-np.abs(mid[:, None] - mid[None, :]) / noise.corr_time_s)
    Lp = np.linalg.cholesky(P)
    s = np.einsum("wv,vcn->wcn", Lp, rng.standard_normal((m, 3, n))) * np.sqrt(noise.tau2)[None, :, None]
    Lv = np.linalg.cholesky(V)
    e = np.einsum("wij,wjn->win", Lv, rng.standard_normal((m, 3, n)))
    err = A[:3] @ (s + e).reshape(3 * m, n) - s.mean(axis=0)  # (3, n)

    def solve(Y: np.ndarray) -> np.ndarray:
        return np.asarray(np.linalg.solve(Sigma, Y), dtype=float)

    got = run_mean_bias_cov(H, C, solve, noise, mid)
    drawn = err @ err.T / n
    np.testing.assert_allclose(np.diag(got), np.diag(drawn), rtol=5 * np.sqrt(2.0 / n))
    np.testing.assert_allclose(
        got, drawn, atol=5 * np.sqrt(2.0 / n) * np.sqrt(np.outer(np.diag(got), np.diag(got))).max()
    )
    assert np.all(np.diag(got) < 0.5 * np.diag(C)[:3])
