"""Orientation-free calibration: exact on ideal data, honest z-scores, agrees with the full fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.estimation.scalar_fit import fit_scalar
from bench.estimation.static_fit import fit_static
from tests.support.static_sim import G_LOCAL, random_truth


def _poses(n: int, seed: int) -> np.ndarray:
    return Rotation.random(n, random_state=seed).inv().apply([0.0, 0.0, G_LOCAL])


def test_ideal_data_give_L_with_L_Lt_equal_K_Kt() -> None:
    b, K = random_truth(np.random.default_rng(1))
    f = _poses(20, 2)
    fit = fit_scalar(b + f @ K.T, np.tile(np.eye(3) * 1e-12, (20, 1, 1)), G_LOCAL)
    np.testing.assert_allclose(fit.bias, b, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fit.L @ fit.L.T, K @ K.T, rtol=0, atol=1e-15)
    assert np.allclose(np.triu(fit.L, 1), 0.0) and np.all(np.diag(fit.L) > 0)
    # L is the lower-triangular factor of the LQ decomposition of K (independent: QR of Kᵀ)
    _, r = np.linalg.qr(K.T)
    np.testing.assert_allclose(fit.L, r.T * np.sign(np.diag(r))[None, :], atol=1e-14)
    np.testing.assert_allclose(fit.residuals_m_s2, 0.0, atol=1e-9)


def test_z_scores_are_honest_over_300_runs() -> None:
    rng = np.random.default_rng(8)
    z = []
    for _ in range(300):
        b, K = random_truth(rng)
        f = _poses(16, int(rng.integers(1 << 30)))
        sd = np.array([5e-6, 6e-6, 7e-6])
        fit = fit_scalar(
            b + f @ K.T + rng.normal(0, sd, (16, 3)), np.tile(np.diag(sd**2), (16, 1, 1)), G_LOCAL
        )
        L_true = np.linalg.cholesky(K @ K.T)
        z.append(np.r_[fit.bias - b, (fit.L - L_true)[np.tril_indices(3)]] / fit.sigma)
    z = np.array(z)
    assert np.mean(np.abs(z) < 3) >= 0.99
    assert np.all((z.std(axis=0) > 0.8) & (z.std(axis=0) < 1.25)), z.std(axis=0)


def test_agrees_with_the_full_fit_on_the_same_windows() -> None:
    """Same noisy window means: K Kᵀ from the known-orientation fit equals L Lᵀ within noise."""
    rng = np.random.default_rng(9)
    b, K = random_truth(rng)
    f = _poses(24, 10)
    sd = 6e-6
    y = b + f @ K.T + rng.normal(0, sd, (24, 3))
    V = np.tile(np.eye(3) * sd**2, (24, 1, 1))
    full, scal = fit_static(f, y, V), fit_scalar(y, V, G_LOCAL)
    np.testing.assert_allclose(scal.bias, full.bias, atol=4 * scal.sigma[:3].max())
    KKt, LLt = full.K @ full.K.T, scal.L @ scal.L.T
    # both within noise of the truth (K ~ 0.0176, sigmas ~ 1e-7): agree to ~ 2·K·σ_K
    np.testing.assert_allclose(LLt, KKt, rtol=0, atol=1e-3 * np.max(KKt))
    assert np.max(np.abs(LLt - K @ K.T)) < 1e-3 * np.max(KKt)


def test_too_few_or_coplanar_windows_are_refused() -> None:
    b, K = random_truth(np.random.default_rng(1))
    f = _poses(8, 3)
    with pytest.raises(ValueError, match="at least 9 static windows"):
        fit_scalar(b + f @ K.T, np.tile(np.eye(3) * 1e-12, (8, 1, 1)), G_LOCAL)
    ang = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    fc = G_LOCAL * np.column_stack([np.cos(ang), np.sin(ang), np.zeros(12)])  # all horizontal
    with pytest.raises(ValueError):
        fit_scalar(b + fc @ K.T, np.tile(np.eye(3) * 1e-12, (12, 1, 1)), G_LOCAL)


def test_window_sandwich_carries_a_scatter_that_follows_the_pose() -> None:
    """Motion only in the windows near +x: the homogeneous excess spreads that scatter over every
    window, so b_x and L_xx, which those windows determine, were 1.5–1.7× their sigma (40 seeds,
    benchmarks/study_sigmas_scalar.py); with the sandwich floor their z RMS is ≈ 1.07. Sampled here
    over 30 seeds with a margin; clean sessions stay within 0.75–1.25."""
    from benchmarks.study_sigmas_scalar import z_scores

    z = z_scores("pose-motion", 200, 30)
    rms = np.sqrt(np.mean(z**2, axis=0))
    assert rms[0] < 1.3 and rms[3] < 1.3, rms
    clean = z_scores("clean", 200, 30)
    assert 0.75 < np.sqrt(np.mean(clean**2)) < 1.25


def test_sandwich_equals_the_model_covariance_when_residuals_match_it() -> None:
    """With weighted residuals of exactly unit size the sandwich is C · m / (m − p) (HC1), so the
    floor scales C by √(m / (m − p)) and keeps its correlations."""
    from bench.estimation.scalar_fit import floor_by_sandwich, window_sandwich

    rng = np.random.default_rng(3)
    Jw = rng.normal(size=(40, 4))
    C = np.linalg.inv(Jw.T @ Jw)
    S = window_sandwich(C, Jw, np.ones(40))
    np.testing.assert_allclose(S, C @ (Jw.T @ Jw) @ C * 40 / 36, rtol=1e-12)
    np.testing.assert_allclose(floor_by_sandwich(C, S), C * 40 / 36, rtol=1e-12)
    np.testing.assert_allclose(floor_by_sandwich(C, 0.5 * C), C, rtol=0)
