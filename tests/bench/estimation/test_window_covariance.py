"""O(m) covariance of window means with a slow wander: against the dense matrix, and GLS under it."""

from __future__ import annotations

import numpy as np
import pytest

from bench.diagnosis.likelihood import NoiseParams, covariance, gls, window_covariance
from bench.estimation.window_covariance import WindowCovariance, fixed_quadratic, invert_blocks


def _blocks(rng: np.random.Generator, m: int) -> np.ndarray:
    A = rng.normal(size=(m, 3, 3))
    return np.einsum("wij,wkj->wik", A, A) + 0.1 * np.eye(3)


@pytest.mark.parametrize(
    ("tau2", "corr_time_s"),
    [([1.0, 0.0, 2.0], 5.0), ([0.5, 0.3, 0.2], 0.0), ([0.0, 0.0, 0.0], 3.0), ([1e-12, 1.0, 1e-9], 100.0)],
)
def test_solve_logdet_and_inverse_blocks_match_dense(tau2: list[float], corr_time_s: float) -> None:
    rng = np.random.default_rng(1)
    m = 9
    mid = rng.permutation(np.arange(m) * 3.0 + rng.uniform(0, 1, m))  # out of time order on purpose
    wc = WindowCovariance(_blocks(rng, m), np.array(tau2), corr_time_s, mid)
    C = wc.dense()
    fac = wc.factor()
    Y = rng.normal(size=(3 * m, 4))
    ref = np.linalg.solve(C, Y)
    np.testing.assert_allclose(fac.solve(Y), ref, rtol=1e-9, atol=1e-12 * np.max(np.abs(ref)))
    assert fac.logdet == pytest.approx(np.linalg.slogdet(C)[1], abs=1e-9)
    Ci = np.linalg.inv(C)
    dense_blocks = np.stack([Ci[3 * w : 3 * w + 3, 3 * w : 3 * w + 3] for w in range(m)])
    np.testing.assert_allclose(fac.inverse_diagonal_blocks(), dense_blocks, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(wc.diagonal(), np.diag(C), rtol=1e-14)


def test_gls_structured_equals_dense_and_exponential_kernel() -> None:
    rng = np.random.default_rng(2)
    m = 20
    V = _blocks(rng, m) * 1e-2
    mid = np.cumsum(rng.uniform(5, 50, m))
    noise = NoiseParams(tau2=np.array([0.3, 0.0, 0.1]), corr_time_s=40.0)
    C = covariance(V, mid, noise)
    # the kernel written out independently: channel x of windows 0 and 3
    assert C[0, 9] == pytest.approx(0.3 * np.exp(-(mid[3] - mid[0]) / 40.0))
    X = rng.normal(size=(3 * m, 5))
    z = rng.normal(size=3 * m)
    a, b = gls(X, z, C), gls(X, z, window_covariance(V, mid, noise))
    np.testing.assert_allclose(b.theta, a.theta, rtol=1e-9)
    np.testing.assert_allclose(b.cov, a.cov, rtol=1e-9)
    assert b.chi2 == pytest.approx(a.chi2, rel=1e-9)
    assert b.loglik_reml == pytest.approx(a.loglik_reml, rel=1e-10)


def test_gls_from_the_fixed_quadratic_equals_dense_and_refuses_other_times() -> None:
    """The wander-free parts computed once (B⁻¹ [X z], [X z]ᵀ B⁻¹ [X z]) give the GLS of the
    dense covariance, for windows out of time order and under several wanders."""
    rng = np.random.default_rng(3)
    m = 15
    V = _blocks(rng, m) * 1e-2
    mid = rng.permutation(np.cumsum(rng.uniform(5, 50, m)))
    X = rng.normal(size=(3 * m, 4))
    z = rng.normal(size=3 * m)
    inv, logdet = invert_blocks(V)
    xz = np.column_stack([X, z])
    fixed = fixed_quadratic(xz, np.matmul(inv, xz.reshape(m, 3, -1)).reshape(3 * m, -1), mid)
    for tau2, tc in (([0.3, 0.0, 0.1], 40.0), ([0.0, 0.0, 0.0], 0.0), ([0.2, 0.2, 0.2], 0.0)):
        noise = NoiseParams(tau2=np.array(tau2), corr_time_s=tc)
        wc = window_covariance(V, mid, noise)
        wc = WindowCovariance(wc.blocks, wc.tau2, wc.corr_time_s, wc.mid_s, inv, logdet)
        a, b = gls(X, z, covariance(V, mid, noise)), gls(X, z, wc, fixed_xz=fixed)
        np.testing.assert_allclose(b.theta, a.theta, rtol=1e-9)
        assert b.loglik_reml == pytest.approx(a.loglik_reml, rel=1e-10)
    other = WindowCovariance(V, np.ones(3), 40.0, mid[::-1].copy())
    with pytest.raises(ValueError, match="other window times"):
        other.factor().quadratic_fixed(fixed)


def test_windows_at_one_time_with_a_correlated_wander_are_refused() -> None:
    wc = WindowCovariance(np.stack([np.eye(3)] * 3), np.ones(3), 10.0, np.array([0.0, 5.0, 5.0]))
    with pytest.raises(ValueError, match="share a time"):
        wc.factor()


def test_non_positive_block_is_named() -> None:
    B = np.stack([np.eye(3), -np.eye(3)])
    with pytest.raises(ValueError, match="window \\[1\\]"):
        WindowCovariance(B, np.zeros(3), 0.0, np.array([0.0, 1.0])).factor()
