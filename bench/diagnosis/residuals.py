"""Where the first-order model and the recording differ: per channel, per window.

Per channel i, the mismatch ratio is χ²_i / (m − 4) with χ²_i = Σ_w r_wi² / s_wi², s_wi²
the window mean's noise variance (own samples plus the slow noise the recording shows),
so 1 means "explained to the noise". The worst window of the worst channel locates the
mismatch; its pose is described by the specific force the recording says it saw.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence

CHANNELS = ("ax", "ay", "az")


@dataclass(frozen=True)
class ResidualSummary:
    """Residual statistics of one model.

    :param resid: (m, 3) window residuals (channel units).
    :param z: (m, 3) residuals over their noise sigma.
    :param channel_ratio: (3,) χ²_i / (m − 4) per channel.
    """

    resid: FloatArray
    z: FloatArray
    channel_ratio: FloatArray


def summarise(ev: StaticEvidence, resid: FloatArray, sigma: FloatArray) -> ResidualSummary:
    """Normalised residuals and per-channel mismatch ratios (module docstring)."""
    z = resid / sigma
    dof = max(ev.m - 4, 1)
    return ResidualSummary(resid=resid, z=z, channel_ratio=np.sum(z**2, axis=0) / dof)


def _pose_text(f: FloatArray, g: float) -> str:
    parts = []
    for i, a in enumerate("xyz"):
        v = f[i] / g
        if abs(v) > 0.05:
            parts.append(f"f_{a} = {v:+.2f} g")
    return ", ".join(parts)


def where(ev: StaticEvidence, summary: ResidualSummary) -> str:
    """One line: the worst channel(s) and the window where the mismatch is strongest."""
    ratio = summary.channel_ratio
    worst = int(np.argmax(ratio))
    bad = [CHANNELS[i] for i in range(3) if ratio[i] > 2.0]
    if not bad:
        return "nowhere beyond the noise"
    w = int(np.argmax(np.abs(summary.z[:, worst])))
    chans = ", ".join(bad)
    return (
        f"{chans}, strongest on {CHANNELS[worst]} in window {ev.labels[w]} "
        f"({_pose_text(ev.f_m_s2[w], ev.g_local_m_s2)}; residual {summary.z[w, worst]:+.1f} sigma)"
    )
