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
(``static_fit``: a common pose scatter and each channel's own excess).

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


def pm_statistic(X: FloatArray, y: FloatArray, v: FloatArray) -> float:
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


def pose_scatter(K: FloatArray, f_m_s2: FloatArray) -> FloatArray:
    """Covariance shape of a pose error in each window's mean, per unit variance of the tilt.

    A window whose unit sits tilted by a small random angle δ (rad, isotropic, variance
    t/g² per axis) sees f + δ × f instead of f: an error perpendicular to f, which the
    channels read as K (δ × f). Its covariance is t · K (I − f̂ f̂ᵀ) Kᵀ with f̂ = f/|f|; the
    same tilt reaches all channels of the window, so the matrix is full, not diagonal.

    :param K: (c, 3) scale matrix, channel unit per m/s².
    :param f_m_s2: (m, 3) specific force per window (m/s²).
    :returns: (m, c, c) K (I − f̂_w f̂_wᵀ) Kᵀ in (channel unit per m/s²)²; times t in
        (m/s²)² it is the window's pose-error covariance in channel units².
    """
    K = np.asarray(K, dtype=float)
    f = np.asarray(f_m_s2, dtype=float)
    fh = f / np.linalg.norm(f, axis=1, keepdims=True)
    P = np.eye(3)[None] - fh[:, :, None] * fh[:, None, :]
    return np.asarray(np.einsum("ia,wab,jb->wij", K, P, K), dtype=float)


def known_share(X: FloatArray, D: FloatArray, v: FloatArray) -> float:
    """Expected share in Q of known random effects: Σ_n Σ_w (P⊥ d_n)_w² / v_w.

    An effect ξ_n d_n (ξ_n of variance 1, the same in every window) adds E[ξ_n² ‖P⊥ d_n‖²] =
    ‖P⊥ d_n‖² to the expectation of the weighted residual sum of squares Q of the fit of y on
    X (P⊥ = I − X (Xᵀ W X)⁻¹ Xᵀ W, W = diag(1/v)): the part of d_n the design cannot absorb.

    :param X: (m, p) design; :param D: (m, n) effects of one standard uncertainty each, in the
        unit of y; :param v: (m,) variances.
    """
    if D.shape[1] == 0:
        return 0.0
    Xw = X / v[:, None]
    theta = np.linalg.solve(X.T @ Xw, Xw.T @ D)
    r = D - X @ theta
    return float(np.sum(r**2 / v[:, None]))


def own_channel_variance(
    X: FloatArray, y: FloatArray, base: FloatArray, *, gated: bool = True, known: FloatArray | None = None
) -> FloatArray:
    """Each channel's own between-window variance τ_i² (Paule-Mandel, χ²-gated).

    After the common pose scatter, a channel may still scatter more than its windows'
    variances ``base`` explain (bias wander of that channel alone). If its generalised
    statistic Q_i = Σ_w r_w,i² / base_w,i of the weighted fit exceeds the
    ``OWN_SCATTER_GATE`` quantile of χ²(m − p), τ_i² solves (Paule & Mandel, J. Res. NBS 87
    (1982) 377)

        Σ_w r_w,i² / (base_w,i + τ_i²) = m − p;

    otherwise τ_i² = 0 (under a common cause alone the channel's share is noise).
    With ``gated=False`` τ_i² is that solution whenever Q_i > m − p (the plain Paule-Mandel
    estimate, 0 otherwise). With ``known`` effects, their expected share (:func:`known_share`)
    is taken out of Q_i first, so the excess holds only what they do not explain:
    Q_i(τ²) − Σ_n ‖P⊥ d_n,i‖²(τ²) = m − p, and τ_i² = 0 when even τ² = 0 leaves it below.

    :param X: (m, p) design shared by the channels.
    :param y: (m, c) window means.
    :param base: (m, c) variances already accounted for (within-window + pose).
    :param known: (n, m, c) known random effects of one standard uncertainty each (channel
        units), or ``None``.
    :returns: (c,) τ² in channel units², not yet inflated by :func:`t_factor`.
    """
    m, p = X.shape
    c = y.shape[1]
    dof = m - p
    own = np.zeros(c)
    if dof <= 0:
        return own
    gate = float(chi2.ppf(OWN_SCATTER_GATE, dof)) if gated else float(dof)
    kn = np.zeros((0, m, c)) if known is None else np.asarray(known, dtype=float)
    for i in range(c):
        yi, bi, di = y[:, i], base[:, i], kn[:, :, i].T

        def q_own(t: float, yi: FloatArray = yi, bi: FloatArray = bi, di: FloatArray = di) -> float:
            return pm_statistic(X, yi, bi + t) - known_share(X, di, bi + t)

        if q_own(0.0) > gate:
            own[i] = solve_decreasing(q_own, dof, float(np.median(bi)))
    return own
