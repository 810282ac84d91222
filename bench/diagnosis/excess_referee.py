"""Head to head of each claim against "unexplained on one channel", out of sample.

A misfit that lives on one channel alone and changes from window to window (a connector that
re-seats at each move) is random against the pose set, but with a dozen windows some
catalogue columns on that channel follow part of it by chance (nonlinearity, cross-coupling),
and so do library terms among the many the library tries; each passes its gate before
``unexplained`` looks. The alternative that describes such a recording is not another column
but a variance: channel c carries its own excess ε_c² from window to window
(``channel_excess``, H1_c). So each column claim E the model holds (a catalogue effect or a
library term) is scored against it, both out of sample:

    claim:        design X (with E),     C(λ, κ)         λ, κ by REML
    unexplained:  design X₋E (without),  C(λ, κ, ε_c²)   λ, κ, ε_c² by REML, c a channel E acts on

(``channel_excess.ExcessModel``; T_c and the pose variance as the model fitted them), and
against the model without E and no excess (a misfit common to the channels is κ's in both:
withdrawn then, but no channel is named). The
score is the leave-one-window-out log predictive density (``loo_log_score``): each window's
three means predicted from the other windows with the coefficients re-estimated without it,
a proper scoring rule, so designs and covariances are compared on one scale (Gneiting &
Raftery, JASA 102 (2007) 359). A claim whose score is not above the best one-channel
alternative's is withdrawn and the channel is flagged unexplained instead. This is also the
whole-signature check: an effect whose physics moves several channels but whose fitted
signature is one channel's scatter loses to that channel's excess.

The pose error is a variance, not a column: it predicts no left-out window, it only shapes
the predictive covariance, as the excess does, and on a dozen windows the two shapes are not
told apart out of sample (a hand-held session whose pose error takes χ²/dof from 2812 to 1.0
lost to one channel's excess, docs/diagnose.md). The two variances meet inside the noise
model instead: an excess that wins a head to head is carried into the selection's noise
(``head_to_head_stage.excess_head_to_head``), where REML weighs it against the pose variance.

A true effect's columns predict a left-out window (the pattern is fixed by the poses), which
an excess variance cannot: it only widens the prediction. Variance parameters are fitted on
all windows (one more for the alternative), which favours the alternative by about half a
nat; measured on the catalogue's detection rows (docs/diagnose.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.catch_all import gls_channel_forms
from bench.diagnosis.channel_excess import ExcessModel, channel_excess
from bench.diagnosis.effects import pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.greedy import backward
from bench.diagnosis.likelihood import window_covariance, without_pose
from bench.diagnosis.model_state import ModelState, design, fit_model, scale_matrix
from bench.diagnosis.refit import ModelFit
from bench.diagnosis.residuals import CHANNELS
from bench.diagnosis.result import Unexplained
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.diagnosis.unexplained import correlating
from bench.diagnosis.wander_cap import SlowNoiseCap
from bench.estimation.window_covariance import WindowCovariance


@dataclass(frozen=True)
class HeadToHead:
    """One catalogue claim against its best one-channel alternative.

    :param effect: the catalogue effect; :param channel: the best alternative's channel (0, 1,
        2), ``None`` when the model without the claim and without an excess is best.
    :param claim_score: leave-one-window-out log predictive density of the model with the
        claim (nats); :param excess_score: of the best alternative without it.
    :param excess_var: ε̂_c² of the alternative (channel units²).
    """

    effect: str
    channel: int | None
    claim_score: float
    excess_score: float
    excess_var: float

    @property
    def withdrawn(self) -> bool:
        """The claim does not predict better than the channel's own excess."""
        return not self.claim_score > self.excess_score


def loo_log_score(X: FloatArray, z: FloatArray, C: WindowCovariance) -> float:
    """Σ_w ln p(y_w | y₋w) (nats): each window's (3,) means given the other windows, θ flat.

    With Q = C⁻¹ and the REML precision P = Q − QX (XᵀQX)⁻¹ XᵀQ, the improper joint density
    of z is ∝ exp(−½ zᵀPz), so y_w | y₋w is normal with precision P_ww and residual
    e_w = P_ww⁻¹ (Pz)_w (the same as predicting with θ̂ re-estimated without window w and the
    wander's conditional mean; Harville, JASA 72 (1977) 320, for P). Then

        ln p(y_w | y₋w) = −½ [(Pz)_wᵀ P_ww⁻¹ (Pz)_w − ln|P_ww| + 3 ln 2π],

    with P_ww = Q_ww − (QX)_w A⁻¹ (QX)_wᵀ and (Pz)_w = (Qz)_w − (QX)_w θ̂, all in O(m) from C's
    factor. −∞ when a window cannot be predicted (X without it loses rank).

    :param X: (3m, p) design; :param z: (3m,) window means; :param C: their covariance.
    """
    fac = C.factor()
    QX, Qz = fac.solve(X), fac.solve(z)
    Qww = fac.inverse_diagonal_blocks()
    A = X.T @ QX
    try:
        Ainv = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return -np.inf
    theta = Ainv @ (X.T @ Qz)
    total = 0.0
    for w in range(C.m):
        rows = slice(3 * w, 3 * w + 3)
        U = QX[rows]
        Pww = Qww[w] - U @ Ainv @ U.T
        Pww = 0.5 * (Pww + Pww.T)
        ev_, vec = np.linalg.eigh(Pww)
        if ev_[0] <= 1e-12 * ev_[-1]:
            return -np.inf
        pz = vec.T @ (Qz[rows] - U @ theta)
        total += -0.5 * (
            float(np.sum(pz * pz / ev_)) - float(np.sum(np.log(ev_))) + 3.0 * np.log(2.0 * np.pi)
        )
    return total


def head_to_heads(
    ev: StaticEvidence, state: ModelState, fixed: FloatArray | None, th: Thresholds = THRESHOLDS
) -> list[HeadToHead]:
    """Each column claim of the model against its best one-channel alternative (module
    docstring), in the order the claims entered: catalogue effects and library terms (the model
    without the claim's columns, an excess on a channel they act on)."""
    assert state.noise is not None and state.fit is not None
    if not state.candidates:
        return []
    K = scale_matrix(state.fit)
    J = pose_response(ev, K)
    cap = SlowNoiseCap(ev, th.cap_alpha)
    model = ExcessModel.build(ev, state.noise if state.pose else without_pose(state.noise), J, fixed, cap)
    z = ev.y.reshape(-1)
    X = design(ev, K, state.candidates)
    _, x_full = model.fit_shared(X, z)
    claim = loo_log_score(X, z, model.covariance(x_full, None))
    rivals: list[tuple[str, list[int], FloatArray, ExcessModel]] = []
    for effect in dict.fromkeys(c.effect for c in state.candidates):
        chans = sorted({i for c in state.candidates if c.effect == effect for i in c.channels})
        X_wo = design(ev, K, [c for c in state.candidates if c.effect != effect])
        rivals.append((effect, chans, X_wo, model))
    out: list[HeadToHead] = []
    for effect, chans, X_wo, alt in rivals:
        _, x0 = alt.fit_shared(X_wo, z)
        best = HeadToHead(effect, None, claim, loo_log_score(X_wo, z, alt.covariance(x0, None)), 0.0)
        for ch in chans:
            _, x1 = alt.fit_channel(X_wo, z, ch, x0)
            score = loo_log_score(X_wo, z, alt.covariance(x1, ch))
            if score > best.excess_score:
                best = HeadToHead(effect, ch, claim, score, alt.size(float(x1[2])))
        out.append(best)
    return out


def excess_referee(
    ev: StaticEvidence,
    state: ModelState,
    fixed: FloatArray | None,
    notes: dict[str, str],
    th: Thresholds = THRESHOLDS,
) -> list[HeadToHead]:
    """Withdraw, worst first, each catalogue claim that loses its head to head (module docstring);
    the model is refitted after each and the rest judged again. Returns the claims withdrawn."""
    lost: list[HeadToHead] = []

    def worst_out(state: ModelState) -> tuple[str, ModelState] | None:
        assert state.noise is not None and state.fit is not None
        losing = [h for h in head_to_heads(ev, state, fixed, th) if h.withdrawn]
        if not losing:
            return None
        h = max(losing, key=lambda h: h.excess_score - h.claim_score)
        lost.append(h)
        state.candidates = [c for c in state.candidates if c.effect != h.effect]
        state.steps = [s for s in state.steps if s.effect != h.effect]
        notes[h.effect] = withdrawn_text(h)
        K = scale_matrix(state.fit)
        state.noise, state.fit, _ = fit_model(ev, state.candidates, state.pose, K, fixed, state.noise, th=th)
        return h.effect, state

    backward(state, worst_out)
    return lost


def withdrawn_text(h: HeadToHead) -> str:
    """Why a claim was withdrawn in its head to head."""
    if h.channel is None:
        return (
            "passed its gate but predicts a left-out window no better than the model without it, "
            f"the noise re-estimated (leave-one-window-out log score {h.claim_score:.1f} with it, "
            f"{h.excess_score:.1f} without): not claimed"
        )
    return (
        f"passed its gate but predicts a left-out window no better than {CHANNELS[h.channel]} carrying "
        f"its own excess of {np.sqrt(h.excess_var):.2g} channel units from window to window "
        f"(leave-one-window-out log score {h.claim_score:.1f} with the claim, {h.excess_score:.1f} "
        f"with the excess instead): not claimed, {CHANNELS[h.channel]} flagged unexplained"
    )


def flag_instead(
    ev: StaticEvidence,
    final: ModelFit,
    state: ModelState,
    K: FloatArray,
    fixed: FloatArray | None,
    left: Unexplained | None,
    lost: tuple[HeadToHead, ...],
    th: Thresholds = THRESHOLDS,
) -> Unexplained | None:
    """``left`` with the channel of the strongest withdrawn claim named, where a claim was withdrawn
    for one channel's excess, ``left`` names none, and that channel's one-channel likelihood ratio
    on the final model passes ``th.unexplained_alpha`` (its p value ½ P(χ²₁ > LR), without the
    factor 3 of ``channel_excess``: the head to head gave the channel). A withdrawal whose
    channel the final model does not show (a misfit common to the channels that one channel's
    excess happened to predict better than the claim) names none."""
    named = [h for h in lost if h.channel is not None]
    if not named or (left is not None and left.channel is not None):
        return left
    assert state.noise is not None
    h = max(named, key=lambda h: h.excess_score - h.claim_score)
    c = h.channel
    assert c is not None
    noise = state.noise if final.pose else without_pose(state.noise)
    J = pose_response(ev, K)
    X = design(ev, K, list(final.candidates))
    ex = channel_excess(ev, X, noise, J, fixed, SlowNoiseCap(ev, th.cap_alpha))
    p = 1.0 if ex.lr[c] <= 0 else 0.5 * float(chi2_dist.sf(ex.lr[c], 1))
    if p >= th.unexplained_alpha:
        return left
    why = (
        f"{CHANNELS[c]}: {h.effect} was withdrawn for {CHANNELS[c]}'s own excess from window to window "
        f"(leave-one-window-out log score {h.excess_score:.1f} against {h.claim_score:.1f}); on the final "
        f"model {CHANNELS[c]} alone scatters by {np.sqrt(ex.excess_var[c]):.2g} channel units beyond "
        f"the shared slow noise (likelihood ratio {ex.lr[c]:.1f})"
    )
    test = (
        f"head to head of {h.effect} against {CHANNELS[c]} carrying its own excess, out of sample; "
        f"one-channel likelihood ratio of {CHANNELS[c]} on the final model (p = {p:.2g})"
    )
    if left is not None:
        return Unexplained(
            chi2_dof=left.chi2_dof,
            test=f"{left.test}; {test}",
            p_value=min(left.p_value, p),
            where=f"{left.where}; {why}",
            correlates_with=left.correlates_with,
            channels=left.channels,
            channel=CHANNELS[c],
        )
    channels: dict[str, float] = {}
    if ev.orientation_known:
        cov = window_covariance(ev.V, ev.mid_s, noise, J, fixed)
        q, e, _ = gls_channel_forms(cov, X, ev.y.reshape(-1))
        channels = {CHANNELS[i]: float(q[i] / max(e[i], 1e-300)) for i in range(3)}
    return Unexplained(
        chi2_dof=float(final.chi2_dof),
        test=test,
        p_value=p,
        where=why,
        correlates_with=correlating(ev, final, th),
        channels=channels,
        channel=CHANNELS[c],
    )
