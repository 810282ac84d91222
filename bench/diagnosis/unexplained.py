"""Whether the final model still fails the recording's own noise (``unexplained`` of
``docs/cli-contract.md``): χ² of the whole model, per channel and channels against each other,
and whether one channel carries a misfit the shared slow noise hides (``channel_excess``);
orientation-free evidence on the magnitude alone, with the one-channel test."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2 as chi2_dist
from scipy.stats import f as f_dist

from bench.diagnosis.catch_all import gls_channel_forms, satterthwaite_tails
from bench.diagnosis.channel_excess import ChannelExcess, channel_excess
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
from bench.diagnosis.wander_cap import SlowNoiseCap


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
    One channel's excess over the shared slow noise: the likelihood-ratio test of
    ``channel_excess`` at ``th.unexplained_alpha``, which keeps its power where the inflated
    wander leaves each channel's χ² only a few degrees of freedom; when it passes, it names the
    channel (``Unexplained.channel``).
    """
    assert state.noise is not None
    alpha = th.unexplained_alpha
    noise = state.noise if final.pose else without_pose(state.noise)
    J = pose_response(ev, K)
    cov = window_covariance(ev.V, ev.mid_s, noise, J, fixed)
    X = design(ev, K, list(final.candidates))
    p = X.shape[1]
    p_all = float(chi2_dist.sf(final.fit.chi2, residual_dof(ev, p)))
    ex = channel_excess(ev, X, noise, J, fixed, SlowNoiseCap(ev, th.cap_alpha))
    if not ev.orientation_known:
        return unexplained_magnitude(ev, final, p_all, ex, th)
    q, e, v = gls_channel_forms(cov, X, ev.y.reshape(-1))
    lo, up = satterthwaite_tails(q, e, v)
    p_ch = np.minimum(1.0, 2.0 * np.minimum(lo, up))
    worst = int(np.argmin(p_ch))
    ratio = q / np.maximum(e, 1e-300)
    nu = 2.0 * e * e / np.maximum(v, 1e-300)
    hi, low = int(np.argmax(ratio)), int(np.argmin(ratio))
    p_pair = min(1.0, 6.0 * float(f_dist.sf(ratio[hi] / max(ratio[low], 1e-300), nu[hi], nu[low])))
    if p_all >= alpha and p_ch[worst] >= alpha / 3 and p_pair >= alpha and ex.p_value >= alpha:
        return None
    named = ex.p_value < alpha
    ch = ex.channel if named else int(np.argmax(ratio))
    z = final.resid[:, ch] / final.sigma[:, ch]
    w = int(np.argmax(np.abs(z)))
    others = [f"{CHANNELS[i]} {ratio[i]:.2f}" for i in range(3) if i != ch]
    where_text = (
        f"{CHANNELS[ch]}: chi2 {q[ch]:.1f} where the noise model expects {e[ch]:.1f} "
        f"(ratio {ratio[ch]:.2f}; {', '.join(others)}), strongest in window {ev.labels[w]} "
        f"(residual {z[w]:+.1f} sigma)"
    )
    if named:
        where_text += "; " + excess_text(ex)
    return Unexplained(
        chi2_dof=float(final.chi2_dof),
        test=(
            f"chi2 at {alpha:g} (whole model, p = {p_all:.2g}); per channel two-sided "
            f"at {alpha / 3:.2g} (worst {CHANNELS[worst]}, p = {p_ch[worst]:.2g}); channels "
            f"against each other, F of {CHANNELS[hi]} over {CHANNELS[low]} at {alpha:g} "
            f"(p = {p_pair:.2g}); {excess_test_text(ex, alpha)}"
        ),
        p_value=float(min(p_all, 3.0 * p_ch[worst], p_pair, ex.p_value)),
        where=where_text,
        correlates_with=correlating(ev, final, th),
        channels={CHANNELS[i]: float(ratio[i]) for i in range(3)},
        channel=CHANNELS[ch] if named else None,
    )


def excess_text(ex: ChannelExcess) -> str:
    """Where-sentence of a passing one-channel test (``channel_excess``)."""
    c = ex.channel
    return (
        f"{CHANNELS[c]} alone scatters from window to window by "
        f"{np.sqrt(ex.excess_var[c]):.2g} channel units beyond the slow noise the channels share "
        f"(likelihood ratio {ex.lr[c]:.1f})"
    )


def excess_test_text(ex: ChannelExcess, alpha: float) -> str:
    """Test-sentence of the one-channel test (``channel_excess``)."""
    return (
        f"one channel's excess over the shared slow noise, likelihood ratio of "
        f"{CHANNELS[ex.channel]} at {alpha:g} (p = {ex.p_value:.2g})"
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
    ev: StaticEvidence,
    final: ModelFit,
    p_all: float,
    ex: ChannelExcess,
    th: Thresholds = THRESHOLDS,
) -> Unexplained | None:
    """The whole-model χ² test and the one-channel test, for orientation-free evidence.

    Each window's orientation is free there (``Thresholds.free_orientation_rad``): two of its three
    residual directions are absorbed by that orientation's variance and only the reading's
    magnitude is tested. A channel's χ² then sums mostly those absorbed directions and sits far
    below what the covariance allots it, whatever the fit, so the per-channel χ² and
    between-channel F tests say nothing and are not made. The likelihood-ratio test of
    ``channel_excess`` stays valid (the free orientation is in its covariance): an excess on
    channel i reaches each window's magnitude in proportion to that channel's share of the
    window's direction, which the shared slow noise does not, and names the channel.
    """
    alpha = th.unexplained_alpha
    named = ex.p_value < alpha
    if p_all >= alpha and not named:
        return None
    z = np.linalg.norm(final.resid / final.sigma, axis=1)
    w = int(np.argmax(z))
    where_text = f"the magnitude of the readings, strongest in window {ev.labels[w]}"
    if named:
        where_text += "; " + excess_text(ex)
    return Unexplained(
        chi2_dof=float(final.chi2_dof),
        test=(
            f"chi2 at {alpha:g} (whole model, p = {p_all:.2g}); orientation-free: only "
            "each reading's magnitude is tested, per-channel chi2 tests need known orientations; "
            + excess_test_text(ex, alpha)
        ),
        p_value=min(p_all, ex.p_value),
        where=where_text,
        correlates_with=correlating(ev, final, th),
        channels={},
        channel=CHANNELS[ex.channel] if named else None,
    )
