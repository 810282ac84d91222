"""Honest covariance of a static window's mean, from the window's own samples.

A window of n samples y_t (n, c) is reduced to its mean ȳ. For white noise
Var(ȳ) = Σ/n, but real sensors also show correlated noise (flicker, bias wander,
Gauss-Markov processes) for which Σ/n is too small by the integrated autocorrelation
time. The method of non-overlapping batch means (Flegal & Jones, "Batch means and
spectral variance estimators in MCMC", Ann. Stat. 38 (2010); also NIST SP1065 §5.2,
where the Allan variance at τ is the variance of consecutive τ-averages) estimates
Var(ȳ) without a noise model:

    split the window into B consecutive batches of length m = n // B,
    batch means z_k (k = 1..B), z̄ their mean,
    Var(ȳ) ≈ (1 / B) · 1 / (B − 1) · Σ_k (z_k − z̄)(z_k − z̄)ᵀ

which is exact in expectation for white noise and stays consistent for correlated
noise whose correlation time is short compared with the batch length. Slow processes
whose correlation time exceeds the window (bias wander between windows) are invisible
inside one window; the fit estimates them from the scatter between windows
(``static_fit.between_window_variance``).

A linear trend over the window is removed before batching only when asked
(``detrend=True``): a drift inside a window is part of the window mean's error, so the
default keeps it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import brentq
from scipy.stats import chi2

FloatArray = npt.NDArray[np.float64]

OWN_SCATTER_GATE = 0.95
"""A channel's own between-window variance is added only if its residual χ² exceeds this
quantile (after the common pose scatter): under a common cause alone the channel's share
is noise, and adding it would overstate the sigmas of the terms that pose errors do not
reach (the diagonal of K, second order in the pose angle)."""

DEFAULT_BATCHES = 10
"""Batches per window: long batches (small bias for correlated noise); the correlation factor is
pooled over the windows of a run, so 9 degrees of freedom per window suffice."""


@dataclass(frozen=True)
class WindowNoise:
    """Noise summary of one static window.

    :param mean: (c,) sample mean of the window.
    :param mean_cov: (c, c) covariance of ``mean`` (batch means).
    :param sample_std: (c,) sample standard deviation of the raw samples.
    :param white_mean_cov: (c, c) covariance of ``mean`` if the noise were white (Σ/n).
    :param n_samples: samples in the window.
    :param n_batches: batches used.
    :param correlation_factor: (c,) ratio of batch-means to white-noise variance of the
        mean per channel: the effective integrated autocorrelation time in samples
        (≈ 1 for white noise).
    """

    mean: FloatArray
    mean_cov: FloatArray
    sample_std: FloatArray
    white_mean_cov: FloatArray
    n_samples: int
    n_batches: int
    correlation_factor: FloatArray


def window_noise(samples: FloatArray, *, n_batches: int = DEFAULT_BATCHES) -> WindowNoise:
    """Mean of one window and the honest covariance of that mean.

    :param samples: (n, c) samples of one static window, any unit.
    :param n_batches: number of batch means B (≥ 2); reduced to n // 4 for short windows
        so that each batch keeps at least 4 samples.
    :returns: :class:`WindowNoise`; covariances in the unit of ``samples`` squared.
    :raises ValueError: fewer than 8 samples, non-finite samples, or ``n_batches < 2``.
    """
    y = np.asarray(samples, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2:
        raise ValueError(f"window samples must be (n, c), got shape {y.shape}")
    n = y.shape[0]
    if n < 8:
        raise ValueError(f"a static window needs at least 8 samples to estimate its noise, got {n}")
    if n_batches < 2:
        raise ValueError(f"n_batches must be at least 2, got {n_batches}")
    if not np.all(np.isfinite(y)):
        bad = int(np.argwhere(~np.isfinite(y))[0, 0])
        raise ValueError(f"window sample {bad} is not finite")
    B = int(min(n_batches, n // 4))
    m = n // B
    # Batches cover the first B*m samples; the mean uses all n (the < B leftover samples
    # change the variance by a factor n/(B m) < 1 + B/n, accounted for below).
    mean = y.mean(axis=0)
    z = y[: B * m].reshape(B, m, -1).mean(axis=1)
    dz = z - z.mean(axis=0)
    cov_batch = (dz.T @ dz) / (B - 1)  # covariance of a batch mean (length m)
    mean_cov = cov_batch * (m / n)  # length-m means -> the n-sample mean, Var ∝ 1/length
    dy = y - mean
    sample_cov = (dy.T @ dy) / (n - 1)
    white = sample_cov / n
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.where(np.diag(white) > 0, np.diag(mean_cov) / np.diag(white), 1.0)
    return WindowNoise(
        mean=mean,
        mean_cov=mean_cov,
        sample_std=np.sqrt(np.diag(sample_cov)),
        white_mean_cov=white,
        n_samples=n,
        n_batches=B,
        correlation_factor=factor,
    )


def pooled_mean_covariances(noises: list[WindowNoise]) -> FloatArray:
    """Covariances of the window means with one correlation factor per channel for the run.

    The sensor's noise process is the same in every window of a run, so its integrated
    autocorrelation time is pooled over windows (ratio of summed batch-means variances
    to summed white variances, 9 degrees of freedom per window combined), floored at 1
    (positive correlation only increases Var(ȳ)). Each window keeps its own sample
    covariance (vibration may differ between windows):

        V_w = D · Σ_w / n_w · D,   D = diag(√φ_c),   φ_c = max(1, Σ_w Vbm_w,cc / Σ_w (Σ_w,cc / n_w))

    :param noises: one :class:`WindowNoise` per window.
    :returns: (m, c, c) covariances of the window means.
    """
    if not noises:
        raise ValueError("no windows to pool")
    bm = np.sum([np.diag(w.mean_cov) for w in noises], axis=0)
    wh = np.sum([np.diag(w.white_mean_cov) for w in noises], axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(wh > 0, bm / wh, 1.0)
    d = np.sqrt(np.maximum(phi, 1.0))
    return np.stack([w.white_mean_cov * np.outer(d, d) for w in noises])


def _pm_statistic(X: FloatArray, y: FloatArray, v: FloatArray) -> float:
    """Generalised Q = Σ r² / v of the weighted LS fit of y on X with variances v."""
    Xw = X / v[:, None]
    theta = np.linalg.solve(X.T @ Xw, Xw.T @ y)
    r = y - X @ theta
    return float(np.sum(r**2 / v))


def solve_decreasing(fun: Callable[[float], float], target: float, scale: float) -> float:
    """Smallest t ≥ 0 with fun(t) = target for a decreasing fun; 0 if fun(0) ≤ target."""
    if fun(0.0) <= target:
        return 0.0
    hi = scale
    for _ in range(200):
        if fun(hi) <= target:
            break
        hi *= 4.0
    else:  # pragma: no cover - Q(t) → 0 as t → ∞, so the loop always ends
        raise RuntimeError("between-window variance did not bracket")
    return float(brentq(lambda t: fun(t) - target, 0.0, hi, xtol=1e-12 * hi, rtol=1e-10))


def t_factor(nu: int) -> float:
    """ν / (ν − 2): variance of Student's t_ν, for a variance estimated with ν dof (3 if ν ≤ 4)."""
    return nu / (nu - 2.0) if nu > 4 else 3.0


def between_window_variance(
    X: FloatArray, y: FloatArray, var_within: FloatArray, K: FloatArray
) -> FloatArray:
    """Additive between-window variance per window and channel (Paule-Mandel moment estimator).

    Window means may scatter about the fit by more than their own samples explain: the
    unit was not exactly where the table says (pose error: the true specific force is
    f rotated by a small angle δ, an error ≈ δ × f perpendicular to f), or a channel's
    bias wandered between windows. Both act on every window independently and are
    modelled as two additive variances, each chosen so that a generalised residual sum
    of squares equals its expectation (Paule & Mandel, J. Res. NBS 87 (1982) 377):

    1. common pose scatter, one value t (m/s²)² for all channels, acting perpendicular
       to gravity: s_w,i² = K_i (I − f̂_w f̂_wᵀ) K_iᵀ and, with 3 (m − p) degrees of freedom,

           Σ_i Σ_w r_w,i² / (v_w,i + t s_w,i²) = 3 (m − p);

    2. on top of it, each channel's own extra τ_i² (channel units²), for scatter that is
       not common (bias wander of one channel), if that channel's χ² after step 1 exceeds
       its 95 % quantile (``OWN_SCATTER_GATE``):

           Σ_w r_w,i² / (v_w,i + t s_w,i² + τ_i²) = m − p.

    Each is 0 when the residuals already agree with the noise. An estimated variance
    with ν degrees of freedom makes standardised errors Student-t_ν rather than normal;
    each estimate is multiplied by ν / (ν − 2), the variance of t_ν, so that the reported
    sigmas stay honest with few windows. Pooling the common part
    over three channels keeps z-scores close to N(0, 1): a plain χ²/dof rescaling with
    the 8 dof of one channel makes z ~ t_8 (3σ coverage 98.3 %).

    :param X: (m, 4) design [1 f] shared by the channels, f in m/s².
    :param y: (m, c) window means.
    :param var_within: (m, c) within-window variances of the means.
    :param K: (c, 3) current scale matrix, channel unit per m/s².
    :returns: (m, c) excess variance per window and channel, channel units squared.
    """
    m, p = X.shape
    c = y.shape[1]
    dof = m - p
    if dof <= 0:
        return np.zeros((m, c))
    f = X[:, 1:4]
    fh = f / np.linalg.norm(f, axis=1, keepdims=True)
    Kf = np.asarray(K, dtype=float) @ fh.T  # (c, m): K_i f̂_w
    s2 = (np.sum(np.asarray(K, dtype=float) ** 2, axis=1)[:, None] - Kf**2).T  # (m, c)
    s2 = np.clip(s2, 0.0, None)
    t_pool = 0.0
    if np.any(s2 > 0):

        def pooled_q(t: float) -> float:
            return sum(_pm_statistic(X, y[:, i], var_within[:, i] + t * s2[:, i]) for i in range(c))

        t_pool = solve_decreasing(pooled_q, c * dof, float(np.median(var_within / np.maximum(s2, 1e-300))))
    base = var_within + t_pool * s2
    gate = float(chi2.ppf(OWN_SCATTER_GATE, dof))
    own = np.zeros(c)
    for i in range(c):
        yi, bi = y[:, i], base[:, i]
        if _pm_statistic(X, yi, bi) > gate:

            def q_own(t: float, yi: FloatArray = yi, bi: FloatArray = bi) -> float:
                return _pm_statistic(X, yi, bi + t)

            own[i] = solve_decreasing(q_own, dof, float(np.median(bi)))
    return t_pool * t_factor(c * dof) * s2 + own[None, :] * t_factor(dof)
