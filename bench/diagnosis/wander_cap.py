"""An upper bound on the slow noise between windows from what the windows themselves show.

The slow noise of ``likelihood`` (bias wander: variance τ², exponential correlation time
T_c) also moves the mean *within* each window. For a window of n samples split into two
adjacent halves of length h, the difference d of the halves' means has, under that
process alone (block means of a first-order Gauss-Markov process),

    E[d²] = τ² g(h, T_c),
    g(h, T) = 2 [ 2 (T/h)² (h/T − 1 + e^(−h/T)) − (T/h)² (1 − e^(−h/T))² ],

and the white noise only adds to it. So, with D_w = d_w² / g(h_w, T_c) pooled over the m
windows of one channel, the upper confidence bound

    τ² ≤ τ²_max(T_c) = Σ_w D_w / χ²_{m}(α)     (α = ``Thresholds.cap_alpha``)

holds whatever the white noise is (dropping it only makes the bound looser). On a
recording whose wander is what the noise model says, the bound lies far above the REML
estimate (inactive); on a recording whose window means disagree by more than any wander
the within-window data allow (a hand-held unit not where its labels say), it stops the
slow noise from absorbing that disagreement, which is then left to the effects (e.g.
``pose_error``) to explain.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.evidence import FloatArray, StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


def half_difference_factor(h_s: FloatArray, corr_time_s: float) -> FloatArray:
    """g(h, T_c) of the module docstring: E[d²] / τ² for halves of length h (s)."""
    x = np.asarray(h_s, dtype=float) / corr_time_s
    r = 1.0 / x
    var_mean = 2.0 * r * r * (x - 1.0 + np.exp(-x))
    cov_adj = r * r * (1.0 - np.exp(-x)) ** 2
    return 2.0 * (var_mean - cov_adj)


def half_differences(ev: StaticEvidence) -> tuple[FloatArray, FloatArray] | None:
    """Squared half-window differences d_w² (m', 3) and half lengths h_w (m',) in s.

    ``None`` when the evidence carries no window samples or fewer than two usable windows.
    """
    if ev.window_samples is None or ev.sample_rate_hz is None:
        return None
    d2, h = [], []
    for x in ev.window_samples:
        n = x.shape[0] // 2
        if n < 2:
            continue
        d = x[n : 2 * n].mean(axis=0) - x[:n].mean(axis=0)
        d2.append(d * d)
        h.append(n / ev.sample_rate_hz)
    if len(d2) < 2:
        return None
    return np.array(d2), np.array(h)


class SlowNoiseCap:
    """τ²_max(T_c) of the module docstring for one recording (half differences computed once)."""

    def __init__(self, ev: StaticEvidence, alpha: float) -> None:
        self._hd = half_differences(ev)
        self._alpha = alpha

    def __call__(self, corr_time_s: float) -> FloatArray | None:
        """(3,) upper bound τ²_max per channel (channel units²); ``None`` if it cannot be formed."""
        if self._hd is None or corr_time_s <= 0:
            return None
        d2, h = self._hd
        D = d2 / half_difference_factor(h, corr_time_s)[:, None]
        return np.asarray(D.sum(axis=0) / float(chi2_dist.ppf(self._alpha, D.shape[0])), dtype=float)


def slow_noise_cap(ev: StaticEvidence, corr_time_s: float, th: Thresholds = THRESHOLDS) -> FloatArray | None:
    """(3,) upper bound τ²_max per channel for correlation time ``corr_time_s`` (channel units²).

    ``None`` when the evidence carries no window samples (the bound cannot be formed) or
    ``corr_time_s`` ≤ 0.
    """
    return SlowNoiseCap(ev, th.cap_alpha)(corr_time_s)
