"""Whether the final model still fails the recording's own noise (``unexplained`` of
``docs/cli-contract.md``): χ² of the whole model, per channel and channels against each other;
orientation-free evidence on the magnitude alone."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2 as chi2_dist
from scipy.stats import f as f_dist

from bench.diagnosis.catch_all import gls_channel_forms, satterthwaite_tails
from bench.diagnosis.effects import pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import window_covariance, without_pose
from bench.diagnosis.model_state import ModelState, design
from bench.diagnosis.refit import ModelFit, residual_dof
from bench.diagnosis.regressors import correlations
from bench.diagnosis.residuals import CHANNELS
from bench.diagnosis.result import Unexplained
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


def unexplained(
    ev: StaticEvidence,
    final: ModelFit,
    state: ModelState,
    K: FloatArray,
    fixed: FloatArray | None,
    th: Thresholds = THRESHOLDS,
) -> Unexplained | None:
    """The final model's χ² tests against the recording's noise (``th.unexplained_alpha``).

    Whole: χ² = rᵀ C⁻¹ r against χ² with the model's residual dof (``refit.residual_dof``).
    Per channel: q_i (``catch_all.channel_forms``)
    against the scaled χ² c_i χ²_{ν_i} of its mean e_i and variance under the final noise
    model, two-sided, at ``th.unexplained_alpha`` / 3 each. Channels against each other: the
    slow noise is one input-referred level, so (q_i/e_i)/(q_j/e_j) ~ F(ν_i, ν_j); the largest
    over the smallest, times 6 ordered pairs, at ``th.unexplained_alpha`` (a channel far below
    what the shared level implies says that level was inflated by another channel's mismatch).
    """
    assert state.noise is not None
    alpha = th.unexplained_alpha
    noise = state.noise if final.pose else without_pose(state.noise)
    cov = window_covariance(ev.V, ev.mid_s, noise, pose_response(ev, K), fixed)
    X = design(ev, K, list(final.candidates))
    p = X.shape[1]
    q, e, v = gls_channel_forms(cov, X, ev.y.reshape(-1))
    lo, up = satterthwaite_tails(q, e, v)
    p_ch = np.minimum(1.0, 2.0 * np.minimum(lo, up))
    p_all = float(chi2_dist.sf(final.fit.chi2, residual_dof(ev, p)))
    worst = int(np.argmin(p_ch))
    ratio = q / np.maximum(e, 1e-300)
    nu = 2.0 * e * e / np.maximum(v, 1e-300)
    hi, low = int(np.argmax(ratio)), int(np.argmin(ratio))
    p_pair = min(1.0, 6.0 * float(f_dist.sf(ratio[hi] / max(ratio[low], 1e-300), nu[hi], nu[low])))
    if not ev.orientation_known:
        return unexplained_magnitude(ev, final, p_all, th)
    if p_all >= alpha and p_ch[worst] >= alpha / 3 and p_pair >= alpha:
        return None
    ch = int(np.argmax(ratio))
    z = final.resid[:, ch] / final.sigma[:, ch]
    w = int(np.argmax(np.abs(z)))
    others = [f"{CHANNELS[i]} {ratio[i]:.2f}" for i in range(3) if i != ch]
    where_text = (
        f"{CHANNELS[ch]}: chi2 {q[ch]:.1f} where the noise model expects {e[ch]:.1f} "
        f"(ratio {ratio[ch]:.2f}; {', '.join(others)}), strongest in window {ev.labels[w]} "
        f"(residual {z[w]:+.1f} sigma)"
    )
    return Unexplained(
        chi2_dof=float(final.chi2_dof),
        test=(
            f"chi2 at {alpha:g} (whole model, p = {p_all:.2g}); per channel two-sided "
            f"at {alpha / 3:.2g} (worst {CHANNELS[worst]}, p = {p_ch[worst]:.2g}); channels "
            f"against each other, F of {CHANNELS[hi]} over {CHANNELS[low]} at {alpha:g} "
            f"(p = {p_pair:.2g})"
        ),
        p_value=float(min(p_all, 3.0 * p_ch[worst], p_pair)),
        where=where_text,
        correlates_with=correlating(ev, final, th),
        channels={CHANNELS[i]: float(ratio[i]) for i in range(3)},
    )


def correlating(ev: StaticEvidence, final: ModelFit, th: Thresholds = THRESHOLDS) -> tuple[str, ...]:
    """'regressor on channel' for each significant correlation of the final residual."""
    names: list[str] = []
    for c in correlations(ev, final.resid, final.sigma, th):
        name = f"{c.regressor} on {CHANNELS[c.channel]}"
        if c.significant and name not in names:
            names.append(name)
    return tuple(names)


def unexplained_magnitude(
    ev: StaticEvidence, final: ModelFit, p_all: float, th: Thresholds = THRESHOLDS
) -> Unexplained | None:
    """The whole-model χ² test alone, for orientation-free evidence.

    Each window's orientation is free there (``Thresholds.free_orientation_rad``): two of its three
    residual directions are absorbed by that orientation's variance and only the reading's
    magnitude is tested. A channel's χ² then sums mostly those absorbed directions and sits far
    below what the covariance allots it, whatever the fit, so the per-channel and
    between-channel tests say nothing and are not made.
    """
    alpha = th.unexplained_alpha
    if p_all >= alpha:
        return None
    z = np.linalg.norm(final.resid / final.sigma, axis=1)
    w = int(np.argmax(z))
    return Unexplained(
        chi2_dof=float(final.chi2_dof),
        test=(
            f"chi2 at {alpha:g} (whole model, p = {p_all:.2g}); orientation-free: only "
            "each reading's magnitude is tested, per-channel tests need known orientations"
        ),
        p_value=p_all,
        where=f"the magnitude of the readings, strongest in window {ev.labels[w]}",
        correlates_with=correlating(ev, final, th),
        channels={},
    )
