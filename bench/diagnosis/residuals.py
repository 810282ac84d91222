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


def where_text(located: str, beyond: bool, claimed: bool, limit: str) -> str:
    """The ``where`` line of a diagnosis, never at odds with its claims.

    :param located: the strongest place of the first-order mismatch, as a phrase.
    :param beyond: whether it lies beyond ``limit`` (then it is the line).
    :param claimed: whether the diagnosis names anything (a finding, a discovered term, an
        unexplained mismatch): then the line says that no single place stands out on its own,
        rather than "nowhere beyond the noise" beside the claims.
    :param limit: the level ``beyond`` was judged at, in words.
    """
    if beyond:
        return located
    if not claimed:
        return "nowhere beyond the noise"
    return f"spread over the recording: nothing beyond {limit} on its own (largest: {located})"


def where(ev: StaticEvidence, summary: ResidualSummary, ratio_limit: float, claimed: bool) -> str:
    """One line: the worst channel(s) and the window where the mismatch is strongest
    (:func:`where_text`; a channel is named when its χ²/dof exceeds ``ratio_limit``)."""
    ratio = summary.channel_ratio
    worst = int(np.argmax(ratio))
    bad = [CHANNELS[i] for i in range(3) if ratio[i] > ratio_limit]
    w = int(np.argmax(np.abs(summary.z[:, worst])))
    place = (
        f"strongest on {CHANNELS[worst]} in window {ev.labels[w]} "
        f"({_pose_text(ev.f_m_s2[w], ev.g_local_m_s2)}; residual {summary.z[w, worst]:+.1f} sigma)"
    )
    located = f"{', '.join(bad)}, {place}" if bad else f"{place}, chi2/dof {ratio[worst]:.2f}"
    return where_text(located, bool(bad), claimed, f"chi2/dof {ratio_limit:g} per channel")
