"""Candidate regressors per window and their correlation with the first-order residuals.

Regressors of a static window w (each (m,)): f_i², |f_i|, f_j·f_k (the input terms the
catalogue's sensor effects add), temperature, time, window order, and the outer-axis
angle (cos, sin) that a base tilt follows. Dynamic recordings would add ω², ω̇ and df/dt;
in a static window they are zero.

Correlation of channel i's whitened residual e_i = r_i / σ_i with regressor x, after x is
made orthogonal to that channel's first-order design [1 f_x f_y f_z] (weighted with
1/σ², so a regressor the first-order model already spans correlates with nothing):

    ρ = Σ e x̃ / (|e| |x̃|),   significant when |ρ| √(m − 5) / √(1 − ρ²) > t_{m−5}(1 − α/(2N)),

with N the number of (regressor, channel) pairs tested (Bonferroni), so that a recording
the first-order model explains shows no correlate with probability ≥ 1 − α.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import t as t_dist

from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


def window_regressors(ev: StaticEvidence) -> dict[str, FloatArray]:
    """Name -> (m,) regressor values (module docstring)."""
    f = ev.f_m_s2
    out: dict[str, FloatArray] = {}
    for i, a in enumerate("xyz"):
        out[f"f_{a}^2"] = f[:, i] ** 2
    for i, a in enumerate("xyz"):
        out[f"|f_{a}|"] = np.abs(f[:, i])
    for j, k, name in ((0, 1, "f_x*f_y"), (0, 2, "f_x*f_z"), (1, 2, "f_y*f_z")):
        out[name] = f[:, j] * f[:, k]
    if ev.has_temperature:
        assert ev.temp_c is not None
        out["temperature"] = ev.temp_c.copy()
    out["time"] = ev.mid_s.copy()
    out["window_order"] = np.arange(ev.m, dtype=float)
    if ev.table_rad is not None:
        out["cos(outer_angle)"] = np.cos(ev.table_rad[:, 0])
        out["sin(outer_angle)"] = np.sin(ev.table_rad[:, 0])
    return out


@dataclass(frozen=True)
class Correlation:
    """One regressor against one channel's residual: ρ, and whether it is significant."""

    regressor: str
    channel: int
    rho: float
    significant: bool


def correlations(
    ev: StaticEvidence, resid: FloatArray, sigma: FloatArray, th: Thresholds = THRESHOLDS
) -> list[Correlation]:
    """Correlations of every regressor with every channel's residual, strongest first.

    :param resid: (m, 3) first-order residuals; :param sigma: (m, 3) their noise sigma.
    Significant: |t| beyond the two-sided ``th.correlation_significance`` quantile, Bonferroni
    over channels and regressors.
    """
    m = ev.m
    dof = m - 5
    out: list[Correlation] = []
    if dof < 1:
        return out
    regs = window_regressors(ev)
    crit = float(t_dist.ppf(1.0 - th.correlation_significance / (2.0 * 3 * len(regs)), dof))
    X = np.column_stack([np.ones(m), ev.f_m_s2])
    for name, x in regs.items():
        for i in range(3):
            w = 1.0 / sigma[:, i]
            Xw = X * w[:, None]
            xw = x * w
            xt = xw - Xw @ np.linalg.lstsq(Xw, xw, rcond=None)[0]
            e = resid[:, i] * w
            nx, ne = float(np.linalg.norm(xt)), float(np.linalg.norm(e))
            if nx <= 1e-9 * max(float(np.linalg.norm(xw)), 1e-300) or ne == 0:
                continue
            rho = float(e @ xt / (nx * ne))
            tval = abs(rho) * np.sqrt(dof) / np.sqrt(max(1.0 - rho * rho, 1e-12))
            out.append(Correlation(name, i, rho, bool(tval > crit)))
    out.sort(key=lambda c: -abs(c.rho))
    return out
