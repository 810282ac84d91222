"""Estimator scatter against the Cramér-Rao bound, and the window-noise estimator."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from bench.estimation.static_fit import fit_static
from bench.estimation.window_noise import pooled_mean_covariances, window_noise
from tests.support.static_sim import G_LOCAL, random_truth


def _balanced_12() -> np.ndarray:
    """±x, ±y, ±z and three ± pairs of diagonals: Σ f = 0 (a balanced, isotropic pose set)."""
    d = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [1, -1, 0], [0, 1, -1]], dtype=float)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return G_LOCAL * np.vstack([d, -d])


@pytest.mark.slow
def test_white_noise_scatter_reaches_the_cramer_rao_bound() -> None:
    """2000 runs, 12 windows × L = 100 white samples: MC std within 10 % of the CRB."""
    rng = np.random.default_rng(21)
    f = _balanced_12()
    m, L, sigma = f.shape[0], 100, np.array([3e-4, 4e-4, 5e-4])
    b, K = random_truth(rng)
    truth = np.concatenate([b, K.ravel()])
    est = []
    for _ in range(2000):
        samples = b + f @ K.T + rng.normal(0.0, sigma, (L, m, 3))
        noises = [window_noise(samples[:, w]) for w in range(m)]
        y = np.array([q.mean for q in noises])
        est.append(fit_static(f, y, pooled_mean_covariances(noises)).params - truth)
    mc_std = np.array(est).std(axis=0)
    # Fisher information of channel i from L samples per window: I = L/σ_i² Σ_w x_w x_wᵀ, x = [1 f].
    info = sum(np.outer(np.r_[1.0, fw], np.r_[1.0, fw]) for fw in f) * L
    crb = np.empty(12)
    for i in range(3):
        c = np.sqrt(np.diag(np.linalg.inv(info / sigma[i] ** 2)))
        crb[i], crb[3 + 3 * i : 6 + 3 * i] = c[0], c[1:]
    # closed form for a balanced set: sd(b_i) = σ_i / √(N L) (the linear model's Cramér-Rao bound)
    np.testing.assert_allclose(crb[:3], sigma / np.sqrt(m * L), rtol=1e-12)
    ratio = mc_std / crb
    assert np.all(np.abs(ratio - 1.0) < 0.10), f"MC/CRB ratios {np.round(ratio, 3)}"


def test_batch_means_match_the_exact_variance_of_an_ar1_mean() -> None:
    """AR(1) noise φ = 0.8: Var(mean of n) from its autocovariance, vs batch means averaged over windows."""
    rng = np.random.default_rng(5)
    phi, n, s = 0.8, 2000, 1.0
    k = np.arange(1, n)
    exact = s**2 / n * (1 + 2 * np.sum((1 - k / n) * phi**k))
    est, white = [], []
    for _ in range(400):
        e = rng.normal(0, s * np.sqrt(1 - phi**2), n)
        x0 = rng.normal(0, s)
        x = lfilter([1.0], [1.0, -phi], e[1:], zi=[phi * x0])[0]
        x = np.r_[x0, x]
        wn = window_noise(x[:, None])
        est.append(wn.mean_cov[0, 0])
        white.append(wn.white_mean_cov[0, 0])
    assert abs(np.mean(est) / exact - 1) < 0.06
    assert np.mean(white) / exact < 0.15  # σ²/n would claim a 9× smaller variance
