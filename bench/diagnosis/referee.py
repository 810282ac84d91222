"""Referees of a selected model: a catalogue effect a library term made redundant is dropped
(``prune_catalogue``), and every structured effect must lower the leave-one-window-out
prediction error of its channels (``referee``, ``loo_scores``)."""

from __future__ import annotations

import numpy as np
from scipy.stats import f as f_dist

from bench.diagnosis.effects import Candidate, pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.greedy import backward, step_alpha
from bench.diagnosis.library import EFFECT
from bench.diagnosis.likelihood import gls, window_covariance
from bench.diagnosis.model_state import ModelState, design, fit_model, scale_matrix
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.window_covariance import WindowCovariance


def prune_catalogue(
    ev: StaticEvidence,
    state: ModelState,
    pool: list[Candidate],
    fixed: FloatArray | None,
    notes: dict[str, str],
    th: Thresholds = THRESHOLDS,
) -> list[str]:
    """Drop catalogue effects that entered before a library term and are not needed once it is in.

    Each catalogue effect of the model is removed in turn (weakest first) and its Wald
    statistic, under the model's noise, judged against the gate it passed to enter; one
    that fails it is dropped and the model refitted (a library term that mimics the
    catalogue never enters in the first place: it is tried after the catalogue).
    """
    assert state.noise is not None and state.fit is not None
    if not any(c.effect.startswith(EFFECT + ":") for c in state.candidates):
        return []
    n_cat = len(pool)

    def weakest_out(state: ModelState) -> tuple[str, ModelState] | None:
        assert state.noise is not None and state.fit is not None
        K = scale_matrix(state.fit)
        X = design(ev, K, state.candidates)
        C = window_covariance(ev.V, ev.mid_s, state.noise, pose_response(ev, K), fixed)
        z = ev.y.reshape(-1)
        full = gls(X, z, C).chi2
        weakest: tuple[float, str, float] | None = None
        for effect in dict.fromkeys(c.effect for c in state.candidates):
            if effect.startswith(EFFECT + ":"):
                continue
            keep = [c for c in state.candidates if c.effect != effect]
            q = sum(len(c.names) for c in state.candidates if c.effect == effect)
            lr = gls(design(ev, K, keep), z, C).chi2 - full
            gate = q * float(f_dist.ppf(1.0 - step_alpha(th.false_alarm, n_cat), q, ev.n_obs - X.shape[1]))
            if lr < gate and (weakest is None or lr / gate < weakest[0]):
                weakest = (lr / gate, effect, lr)
        if weakest is None:
            return None
        _, effect, lr = weakest
        state.candidates = [c for c in state.candidates if c.effect != effect]
        state.steps = [s for s in state.steps if s.effect != effect]
        terms = ", ".join(c.label for c in state.candidates if c.effect.startswith(EFFECT + ":"))
        notes[effect] = (
            f"entered before the library's {terms} and is not needed once it is in "
            f"(its statistic falls to {lr:.1f}, below its gate): dropped"
        )
        state.noise, state.fit, _ = fit_model(ev, state.candidates, state.pose, K, fixed, state.noise, th=th)
        return effect, state

    return backward(state, weakest_out)[1]


def loo_scores(ev: StaticEvidence, X: FloatArray, C: WindowCovariance) -> FloatArray:
    """(3,) leave-one-window-out prediction error per channel: Σ_w r_wi² / C_ww,ii with
    r_w = y_w − X_w θ̂₋w, θ̂₋w the GLS estimate without window w's three rows (C's submatrix).

    In O(m), from Q = C⁻¹ (its factor and diagonal blocks Q_ww): the inverse of C without
    window w is Q₋₋ − Q₋w Q_ww⁻¹ Q_w₋ (the Schur complement), so with U_w = (QX)_w − Q_ww X_w
    and u_w = (Qz)_w − Q_ww z_w, the reduced normal equations are

        A₋w = XᵀQX − U_wᵀX_w − X_wᵀU_w − X_wᵀQ_wwX_w − U_wᵀQ_ww⁻¹U_w,
        b₋w = XᵀQz − U_wᵀz_w − X_wᵀu_w − X_wᵀQ_wwz_w − U_wᵀQ_ww⁻¹u_w,

    θ̂₋w = A₋w⁻¹ b₋w (Harville, "Matrix Algebra From a Statistician's Perspective", 1997, §8.5).

    Orientation-free evidence: each window's covariance carries its free orientation, so a
    channel's r_wi² / C_ww,ii is near 0 whatever the fit (the orientation's variance swamps
    the channel) and an effect's gain was noise. There each window scores its whole
    prediction error r_wᵀ C_ww⁻¹ r_w (C_ww = B_w + diag τ², the window's own 3 × 3 block of C;
    only the reading's magnitude is evidence), given to every channel.
    """
    z = ev.y.reshape(-1)
    fac = C.factor()
    QX, Qz = fac.solve(X), fac.solve(z)
    Qww = fac.inverse_diagonal_blocks()
    A, b = X.T @ QX, X.T @ Qz
    diag = C.diagonal()
    out = np.zeros(3)
    for w in range(ev.m):
        rows = slice(3 * w, 3 * w + 3)
        Xw, zw, Q = X[rows], z[rows], Qww[w]
        U = QX[rows] - Q @ Xw
        u = Qz[rows] - Q @ zw
        QiU = np.linalg.solve(Q, np.column_stack([U, u]))
        Aw = A - U.T @ Xw - Xw.T @ U - Xw.T @ Q @ Xw - U.T @ QiU[:, :-1]
        bw = b - U.T @ zw - Xw.T @ u - Xw.T @ Q @ zw - U.T @ QiU[:, -1]
        try:
            th = np.linalg.solve(Aw, bw)
        except np.linalg.LinAlgError:
            return np.full(3, np.inf)
        r = zw - Xw @ th
        if ev.orientation_known:
            out += r * r / diag[rows]
        else:
            out += float(r @ np.linalg.solve(C.blocks[w] + np.diag(C.tau2), r))
    return out


def referee(
    ev: StaticEvidence,
    state: ModelState,
    fixed: FloatArray | None,
    notes: dict[str, str],
    th: Thresholds = THRESHOLDS,
) -> list[str]:
    """Out-of-sample referee of the structured effects (catalogue and library).

    Each effect in the model must lower the leave-one-window-out prediction error
    (``loo_scores``) of the channels it acts on, under the model's noise; a term that only
    bends the fit towards the windows it was fitted to (a random pattern that a few columns
    happen to follow) predicts a left-out window no better than the model without it. The
    worst offender is dropped and the model refitted, until every effect earns its place.
    Returns the effects dropped.
    """

    def worst_out(state: ModelState) -> tuple[str, ModelState] | None:
        assert state.noise is not None and state.fit is not None
        K = scale_matrix(state.fit)
        effects = list(dict.fromkeys(c.effect for c in state.candidates))
        if not effects:
            return None
        C = window_covariance(ev.V, ev.mid_s, state.noise, pose_response(ev, K), fixed)
        full = loo_scores(ev, design(ev, K, state.candidates), C)
        worst: tuple[float, str, float, float] | None = None
        for effect in effects:
            mine = [c for c in state.candidates if c.effect == effect]
            chans = sorted({i for c in mine for i in c.channels})
            keep = [c for c in state.candidates if c.effect != effect]
            without = loo_scores(ev, design(ev, K, keep), C)
            gain = float(np.sum(without[chans]) - np.sum(full[chans]))
            if gain <= 0 and (worst is None or gain < worst[0]):
                worst = (gain, effect, float(np.sum(without[chans])), float(np.sum(full[chans])))
        if worst is None:
            return None
        gain, effect, before, after = worst
        state.candidates = [c for c in state.candidates if c.effect != effect]
        state.steps = [s for s in state.steps if s.effect != effect]
        notes[effect.removeprefix(EFFECT + ":")] = (
            "passed its gate but does not predict a left-out window better than the model without it "
            f"(leave-one-window-out chi2 {after:.1f} with it, {before:.1f} without): a pattern the "
            "windows happen to follow, not claimed"
        )
        state.noise, state.fit, _ = fit_model(ev, state.candidates, state.pose, K, fixed, state.noise, th=th)
        return effect, state

    return backward(state, worst_out)[1]
