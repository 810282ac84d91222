"""``settling``: the table still rings after a move when the window starts.

A ring of the table structure after a stop, δθ(s) = A·e^(−s/τ)·sin(2π f s) about the axes
that moved, adds to the window's samples a decaying oscillation of variance
½ (S A)² e^(−2s/τ) (S the window mean's sensitivity to that axis's angle): the early part
of a window scatters more than its late part. Test, over the 3m window-channels, of the
log variance ratio L = ln(s²_early / s²_late) (early: the first ``EARLY_S`` after the
window starts; late: its second half): mean(L) / (sd(L)/√(3m)) against Student's t at the
false-alarm level. Without the window samples (evidence reduced to means) it cannot be
tested.

Duration (the contract's ``duration_s``): the excess variance of the ring decays as
e^(−2s/τ). With R_k the mean over window-channels of (variance in second k of the
window) / (variance of its second half), R_k = 1 + B e^(−2 s_k/τ) is fitted by weighted
least squares (s_k the bin centre); the bench's convention for the ring
(docs/physics-model.md: amplitude 0.05° decaying to 1e-4°) gives
duration_s = τ · ln(0.05 / 1e-4), its sigma from the fit's covariance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import curve_fit
from scipy.stats import t as t_dist

from bench.diagnosis.effects.base import Candidate, FloatArray, ParamSpec
from bench.diagnosis.evidence import StaticEvidence

EARLY_S = 2.0
"""Length of the early part of each window (s), capped at a quarter of the window."""
RING_DECADES = math.log(0.05 / 1e-4)
"""ln(initial ring amplitude / floor) of the bench's settling convention (docs/physics-model.md)."""
BIN_S = 1.0


@dataclass(frozen=True)
class SettlingTest:
    """Result of :func:`settling_test`: t statistic, its dof, mean log variance ratio."""

    t: float
    dof: int
    mean_log_ratio: float

    def p_value(self) -> float:
        """One-sided p value of the t statistic."""
        return float(t_dist.sf(self.t, self.dof))


def settling_test(window_samples: tuple[FloatArray, ...], sample_rate_hz: float) -> SettlingTest:
    """Early-versus-late variance test of the module docstring.

    :param window_samples: per window (n_w, 3) raw samples.
    :param sample_rate_hz: sampling rate (Hz).
    """
    L = []
    for x in window_samples:
        n = x.shape[0]
        n_early = min(round(EARLY_S * sample_rate_hz), n // 4)
        if n_early < 8:
            continue
        early = x[:n_early].var(axis=0, ddof=1)
        late = x[n // 2 :].var(axis=0, ddof=1)
        ok = (early > 0) & (late > 0)
        L.extend(np.log(early[ok] / late[ok]).tolist())
    a = np.array(L)
    if a.size < 3:
        return SettlingTest(0.0, max(a.size - 1, 1), 0.0)
    sd = float(a.std(ddof=1))
    t = float(a.mean() / (sd / np.sqrt(a.size))) if sd > 0 else 0.0
    return SettlingTest(t, a.size - 1, float(a.mean()))


def settling_duration(window_samples: tuple[FloatArray, ...], sample_rate_hz: float) -> tuple[float, float]:
    """(duration_s, sigma) of the ring from the decay of the excess variance (module docstring).

    :raises ValueError: windows too short or the decay cannot be fitted.
    """
    nb = max(round(BIN_S * sample_rate_hz), 4)
    ratios: list[FloatArray] = []
    for x in window_samples:
        n = x.shape[0]
        k = (n // 2) // nb
        if k < 3:
            continue
        late = x[n // 2 :].var(axis=0, ddof=1)
        bins = x[: k * nb].reshape(k, nb, 3).var(axis=1, ddof=1)
        ok = late > 0
        ratios.extend((bins[:, ok] / late[ok]).T)
    if len(ratios) < 3:
        raise ValueError("settling: windows too short to follow the decay of the ring")
    k = min(r.size for r in ratios)
    a = np.array([r[:k] for r in ratios])
    R = a.mean(axis=0)
    sd = np.maximum(a.std(axis=0, ddof=1) / math.sqrt(a.shape[0]), 1e-12)
    s = (np.arange(k) + 0.5) * BIN_S

    def model(s: FloatArray, b: float, tau: float) -> FloatArray:
        return 1.0 + b * np.exp(-2.0 * s / tau)

    try:
        p0 = (max(R[0] - 1.0, 1e-3), 2.0)
        p, cov = curve_fit(model, s, R, p0=p0, sigma=sd, bounds=([0, 0.05], [np.inf, 1e3]))
    except (RuntimeError, ValueError) as exc:
        raise ValueError(f"settling: the decay of the ring could not be fitted ({exc})") from exc
    tau_sigma = float(np.sqrt(max(cov[1, 1], 0.0)))
    return float(p[1] * RING_DECADES), tau_sigma * RING_DECADES


@dataclass(frozen=True)
class Settling:
    """``settling`` (module docstring)."""

    id: str = "settling"
    kind: str = "window"
    parameters: tuple[ParamSpec, ...] = (ParamSpec("duration_s", "s", ()),)
    explanation: str = (
        "the table structure still rings after a move when the window starts, so the first "
        "seconds of each window scatter more than the rest"
    )

    def observable(self, ev: StaticEvidence) -> tuple[bool, str]:
        if ev.window_samples is None or ev.sample_rate_hz is None:
            return False, "needs the windows' samples, not only their means"
        return True, f"first {EARLY_S:g} s of each window against its second half"

    def candidates(self, ev: StaticEvidence) -> list[Candidate]:
        return []


SETTLING = Settling()
