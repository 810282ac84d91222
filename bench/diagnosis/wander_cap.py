"""An upper bound on the slow noise between windows from what the windows themselves show.

The slow noise of ``likelihood`` (bias wander: variance τ², exponential correlation time
T_c) also moves the mean *within* each window. For a window of n samples split into two
adjacent halves of length h, the difference d of the halves' means has, under that
process alone (block means of a first-order Gauss-Markov process),

    E[d²] = τ² g(h, T_c),
    g(h, T) = 2 [ 2 (T/h)² (h/T − 1 + e^(−h/T)) − (T/h)² (1 − e^(−h/T))² ],

and the white noise adds w_w = 4 s_w² / n_w, s_w² = ⟨(x_{k+1} − x_k)²⟩ / 2 the window's
sample variance read from successive differences (blind to the slow noise). Each
channel's d_w ~ N(0, τ² g_w + w_w), nearly independent between windows, so

    S(τ²) = Σ_w d_w² / (τ² g(h_w, T_c) + w_w) ~ χ²_m

and S falls as τ² grows: the upper confidence bound τ²_max(T_c) is the root of
S(τ²) = χ²_m(α) (α = ``Thresholds.cap_alpha``, lower-tail quantile), 0 when even
S(0) < χ²_m(α). Positively correlated samples (a DAQ's anti-alias filter) make s_w²
read low, which only loosens the bound; with w_w = 0 it is the white-blind bound
Σ_w (d_w² / g_w) / χ²_m(α), which it never exceeds. Each channel is bounded by its own
samples, so a mismatch on one channel cannot raise the slow noise the others are allowed.
On a recording whose wander is what the noise model says, the bound lies above the REML
estimate (inactive); on a recording whose window means disagree by more than any wander
the within-window data allow (a hand-held unit not where its labels say), it stops the
slow noise from absorbing that disagreement, which is then left to the effects (e.g.
``pose_error``) to explain.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq
from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.evidence import FloatArray, StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


def half_difference_factor(h_s: FloatArray, corr_time_s: float) -> FloatArray:
    """g(h, T_c) of the module docstring: E[d²] / τ² for halves of length h (s).

    With x = h / T_c the closed form's two terms are each near 1 when x is small and cancel
    to g ≈ 4x/3, with a rounding error of about 1e−16 / x² (1e−16 / x³ relative): at
    x ~ 1e−5 about 10 %, at x ~ 1e−6 (a day's recording with T_c of a few spans and halves of
    a few seconds) larger than g itself, which then came out negative. Below
    x = :data:`SERIES_BELOW` g is summed as its series,
    g = 2 (2x − 3 + 4 e^(−x) − e^(−2x)) / x² = 2 Σ_{k≥3} (−1)^k (4 − 2^k) x^(k−2) / k!
    (= 4x/3 − x² + …); above it the closed form is kept as it is (relative error about 1e−7
    at x = 1e−3, less above).
    """
    x = np.asarray(h_s, dtype=float) / corr_time_s
    r = 1.0 / x
    var_mean = 2.0 * r * r * (x - 1.0 + np.exp(-x))
    cov_adj = r * r * (1.0 - np.exp(-x)) ** 2
    closed = 2.0 * (var_mean - cov_adj)
    small = x < SERIES_BELOW
    if not np.any(small):
        return np.asarray(closed, dtype=np.float64)
    xs = np.where(small, x, 0.0)
    series = np.zeros_like(xs)
    term = np.full_like(xs, 0.5)  # x^(k−2) / k!, k = 2
    for k in range(3, 12):  # the last term kept, 2^11 x^9 / 11!, is below 1e−30 of g
        term = term * xs / k
        series = series + (-1.0) ** k * (4.0 - 2.0**k) * term
    return np.asarray(np.where(small, 2.0 * series, closed), dtype=np.float64)


SERIES_BELOW = 1e-3
"""x = h / T_c below which g is summed as its series (``half_difference_factor``)."""


def half_differences(ev: StaticEvidence) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """Squared half-window differences d_w² (m', 3), half lengths h_w (m',) in s and the white
    noise's share of d_w², w_w = 4 s_w² / n_w (m', 3), of the module docstring.

    ``None`` when the evidence carries no window samples or fewer than two usable windows.
    """
    if ev.window_samples is None or ev.sample_rate_hz is None:
        return None
    d2, h, w = [], [], []
    for x in ev.window_samples:
        n = x.shape[0] // 2
        if n < 2:
            continue
        d = x[n : 2 * n].mean(axis=0) - x[:n].mean(axis=0)
        s2 = np.mean(np.diff(x[: 2 * n], axis=0) ** 2, axis=0) / 2.0
        d2.append(d * d)
        h.append(n / ev.sample_rate_hz)
        w.append(2.0 * s2 / n)
    if len(d2) < 2:
        return None
    return np.array(d2), np.array(h), np.array(w)


def upper_bound(d2: FloatArray, g: FloatArray, w: FloatArray, q: float) -> float:
    """Root τ² ≥ 0 of Σ d2 / (τ² g + w) = q for one channel (d2, g, w: (m,)); 0 if none.

    S(τ²) of the module docstring falls monotonically from S(0) to 0, so the root is unique.
    """
    if not np.any(d2 > 0):
        return 0.0

    def excess(t2: float) -> float:
        return float(np.sum(d2 / (t2 * g + w))) - q

    hi = float(np.sum(d2 / g)) / q  # the white-blind bound: S(hi) ≤ q there
    lo = 0.0 if np.all(w > 0) else 1e-12 * hi  # S(0) is infinite where a window has w = 0
    if excess(lo) <= 0:
        return lo
    if excess(hi) >= 0:
        return hi
    return float(brentq(excess, lo, hi, xtol=1e-6 * hi, rtol=1e-10))


class SlowNoiseCap:
    """τ²_max(T_c) of the module docstring for one recording (half differences computed once)."""

    def __init__(self, ev: StaticEvidence, alpha: float) -> None:
        self._hd = half_differences(ev)
        self._alpha = alpha

    def __call__(self, corr_time_s: float) -> FloatArray | None:
        """(3,) upper bound τ²_max per channel (channel units²); ``None`` if it cannot be formed."""
        if self._hd is None or corr_time_s <= 0:
            return None
        d2, h, w = self._hd
        g = half_difference_factor(h, corr_time_s)
        q = float(chi2_dist.ppf(self._alpha, d2.shape[0]))
        return np.array([upper_bound(d2[:, c], g, w[:, c], q) for c in range(d2.shape[1])])


def slow_noise_cap(ev: StaticEvidence, corr_time_s: float, th: Thresholds = THRESHOLDS) -> FloatArray | None:
    """(3,) upper bound τ²_max per channel for correlation time ``corr_time_s`` (channel units²).

    ``None`` when the evidence carries no window samples (the bound cannot be formed) or
    ``corr_time_s`` ≤ 0.
    """
    return SlowNoiseCap(ev, th.cap_alpha)(corr_time_s)
