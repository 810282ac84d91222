"""``settling``: the table still rings after a move when the window starts.

A ring of the table structure after a stop, δθ(s) = A·e^(−s/τ)·sin(2π f s) about the axes
that moved, adds to the window's samples a decaying oscillation of variance
½ (S A)² e^(−2s/τ) (S the window mean's sensitivity to that axis's angle): the early part
of a window scatters more than its late part. Test, over the 3m window-channels, of the
log variance ratio L = ln(s²_early / s²_late) (early: the first ``EARLY_S`` after the
window starts; late: its second half): mean(L) / (sd(L)/√(3m)) against Student's t at the
false-alarm level. Without the window samples (evidence reduced to means) it cannot be
tested.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import t as t_dist

from bench.diagnosis.effects.base import Candidate, FloatArray, ParamSpec
from bench.diagnosis.evidence import StaticEvidence

EARLY_S = 2.0
"""Length of the early part of each window (s), capped at a quarter of the window."""


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
