"""One selection step's best fixed-column candidate (``select``'s catalogue and library groups).

A candidate (fixed columns appended to the design) is admissible only if

1. it is observable: its columns keep at least ``Thresholds.relative_leverage_min`` of their norm
   outside the span of the current design (else bias, K and the effects already in the
   model would absorb it: it is reported as indistinguishable, not guessed);
2. its statistic passes the gate at α = ``Thresholds.false_alarm`` / N (N candidates in the step):
   LR = Δχ² = χ²_current − χ²_extended, both under the noise re-estimated (REML) under the
   extended model (the Wald statistic of the q new columns), must exceed q·F_{1−α}(q, n − p),
   p the extended design's columns (F rather than χ²_q because the noise level is estimated
   from the same n observations);
3. its BIC change Δ = −LR + q ln n is negative.

Among the admissible candidates the one with the lowest BIC change is chosen. Candidates are
ranked first with the current noise held fixed and only the best ``Thresholds.shortlist`` are
re-fitted with their own noise (the REML fit is the expensive part).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.stats import f as f_dist

from bench.diagnosis.effects import Candidate, leverage, pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.greedy import Trial, admits
from bench.diagnosis.likelihood import GlsFit, NoiseParams, window_covariance
from bench.diagnosis.model_state import ModelState, design, fit_model, lr_fixed, whitened_lr
from bench.diagnosis.profiled import resolve
from bench.diagnosis.refit import residual_dof
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.diagnosis.wander_cap import SlowNoiseCap
from bench.diagnosis.wander_modes import (
    WANDER_LIKE,
    follows_time,
    modulated_lr,
    modulated_note,
    pose_modulated,
    wander_note,
)

LIB = "discovered:"
"""Effect prefix of the library's terms (``library.EFFECT``)."""


def structured_step(
    ev: StaticEvidence,
    pool: list[Candidate],
    state: ModelState,
    K: FloatArray,
    fixed: FloatArray | None,
    alpha: float,
    notes: dict[str, str],
    prescreen: float = 0.0,
    simplicity: dict[str, int] | None = None,
    cap: SlowNoiseCap | None = None,
    wander_notes: dict[str, str] | None = None,
    th: Thresholds = THRESHOLDS,
) -> tuple[float, Candidate, float, tuple[NoiseParams, GlsFit, FloatArray]] | None:
    """The best admissible fixed-column candidate of ``pool`` (gate at ``alpha`` each), or ``None``.

    ``prescreen`` (a fraction of the gate): candidates whose statistic under the current noise
    is below it are not re-fitted. ``simplicity`` (label -> degree): among admissible
    candidates within ``th.tie_chi2`` of the best (statistic under the windows' own scatter for
    the shortlist, then 2 ℓ_ML of the extended model under its own noise) the one of lowest
    degree is tried and enters. A drift or temperature claim (:data:`WANDER_LIKE`) must also
    beat the trend the measured wander makes: its statistic is the smaller of the one above and
    the likelihood ratio with each channel's own slow wander re-estimated in both models; so
    must a library term in time or temperature alone, and a pose-modulated library term in
    time or temperature must also pass the gate with the wander's leading mode (a trend) on
    its channel in the model (``wander_modes.modulated_lr``). Why such a claim was refused
    goes to ``notes`` (``wander_notes`` when given, the library's leverage notes being many).
    """
    assert state.noise is not None
    wander_notes = notes if wander_notes is None else wander_notes
    n = ev.n_obs
    X = design(ev, K, state.candidates)
    tried = [c for c in pool if not state.holds(c)]
    tried = [
        r
        for c in tried
        if (r := c if c.family is None else resolve(ev, c, X, state.noise, K, fixed, alpha, notes, th))
        is not None
    ]
    if not tried:
        return None
    cols = [c.columns(ev, K) for c in tried]
    rank_noise = state.noise
    if simplicity is not None:
        # rank the library against the windows' own scatter: a slow noise inflated by the very
        # mismatch a term would explain makes every term look alike
        rank_noise = replace(state.noise, tau2=np.zeros(3))
    lr0, lev = whitened_lr(ev, X, np.hstack(cols), rank_noise, K, fixed)
    ranked: list[tuple[float, Candidate]] = []
    col = 0
    Qx = np.linalg.qr(X)[0]  # one factor of the design for every candidate's leverage
    for cand, a in zip(tried, cols, strict=True):
        q = a.shape[1]
        lv = leverage(X, a, Qx)
        lev_min = th.relative_leverage_min
        if np.any(lv < lev_min) or np.any(lev[col : col + q] < lev_min):
            notes[cand.label] = (
                f"cannot be told apart from the model's other terms on this pose set "
                f"(only {float(np.min(lv)):.1e} of its signature is independent of them)"
            )
        elif q == 1:
            ranked.append((float(lr0[col]), cand))
        else:
            ranked.append((lr_fixed(ev, X, np.hstack([X, a]), state.noise, K, fixed), cand))
        col += q
    ranked.sort(key=lambda r: -r[0])
    if simplicity and len(ranked) > th.shortlist:
        # the simplest of the terms alike the best (within tie_chi2) is re-fitted too
        pos = {id(c): k for k, c in enumerate(tried)}
        Ap = np.hstack(cols)
        Ap = Ap - Qx @ (Qx.T @ Ap)
        Ap /= np.maximum(np.linalg.norm(Ap, axis=0), 1e-300)
        s_top = Ap[:, pos[id(ranked[0][1])]]
        near = [
            r
            for r in ranked
            if r[0] >= ranked[0][0] - th.tie_chi2
            and abs(float(Ap[:, pos[id(r[1])]] @ s_top)) > th.alike_cosine
        ]
        first = min(near, key=lambda r: (simplicity.get(r[1].label, 0), -r[0]))
        if first not in ranked[: th.shortlist]:
            ranked = [*ranked[: th.shortlist - 1], first]
    admissible = []
    null_own: tuple[NoiseParams, GlsFit, FloatArray] | None = None
    for lr_now, cand in ranked[: th.shortlist]:
        q = len(cand.names)
        gate = gate_of(cand, alpha, residual_dof(ev, X.shape[1] + q))
        if lr_now < prescreen * gate:
            continue
        model1 = fit_model(ev, [*state.candidates, cand], state.pose, K, fixed, state.noise, cap=cap)
        noise1, _fit1, K1 = model1
        X1 = design(ev, K1, [*state.candidates, cand])
        lr = lr_fixed(ev, X1[:, : X.shape[1]], X1, noise1, K1, fixed)
        gate = gate_of(cand, alpha, residual_dof(ev, X1.shape[1]))
        term = cand.names[0] if cand.effect.startswith(LIB) else ""
        wander_like = cand.effect in WANDER_LIKE or (follows_time(term) and not pose_modulated(term))
        if term and follows_time(term) and pose_modulated(term) and lr > gate:
            C1 = window_covariance(ev.V, ev.mid_s, noise1, pose_response(ev, K1), fixed)
            lr_mod, b = modulated_lr(
                ev, X1[:, : X.shape[1]], X1[:, X.shape[1] :], cand.channels[0], C1, th.relative_leverage_min
            )
            gate_mod = gate_of(cand, alpha, residual_dof(ev, X1.shape[1] + b))
            if lr_mod <= gate_mod:
                wander_notes[cand.label] = modulated_note(cand.label, lr, lr_mod, gate_mod)
                continue
        if wander_like and lr > gate:
            if null_own is None:
                null_own = fit_model(
                    ev, state.candidates, state.pose, K, fixed, state.noise, cap=cap, own=True
                )
            ext_own = fit_model(
                ev, [*state.candidates, cand], state.pose, K, fixed, null_own[0], cap=cap, own=True
            )
            lr_wander = max(0.0, 2.0 * (ext_own[1].loglik_ml - null_own[1].loglik_ml))
            if lr_wander <= gate:
                wander_notes[cand.label] = wander_note(cand.effect, lr, lr_wander, gate, null_own[0])
            lr = min(lr, lr_wander)
        dbic = -lr + (q + cand.extra_params) * math.log(n)
        if admits(Trial(cand, lr, gate, dbic)):
            admissible.append((dbic, cand, lr, model1))
    if not admissible:
        return None
    best = min(admissible, key=lambda a: a[0])
    if simplicity:
        # one column each: compare the extended models' own likelihoods (ML, each under its noise)
        top = max(admissible, key=lambda a: a[3][1].loglik_ml)

        def sig(c: Candidate) -> FloatArray:
            a = c.columns(ev, K)[:, 0]
            a = a - Qx @ (Qx.T @ a)
            return a / max(float(np.linalg.norm(a)), 1e-300)

        s_top = sig(top[1])
        alike = [
            a
            for a in admissible
            if 2.0 * (top[3][1].loglik_ml - a[3][1].loglik_ml) <= th.tie_chi2
            and abs(float(sig(a[1]) @ s_top)) > th.alike_cosine
        ]
        best = min(alike, key=lambda a: (simplicity.get(a[1].label, 0), -a[3][1].loglik_ml))
    else:
        # effects whose signatures coincide beyond the model and fit alike are a tie, not a
        # choice the data make: the one listed first in the pool (the catalogue's order) enters
        alike = [
            a
            for a in admissible
            if a[0] <= best[0] + th.tie_chi2 and same_signature(ev, K, X, a[1], best[1], th)
        ]
        best = min(alike, key=lambda a: tried.index(a[1]))
    return best


def gate_of(cand: Candidate, alpha: float, dof: int) -> float:
    """q·F_{1−α/tries}(q, dof): a candidate's gate at the step's α, shared over the effective
    number of values its search tried (``Candidate.tries``, 1 for fixed columns)."""
    q = len(cand.names)
    return q * float(f_dist.ppf(1.0 - alpha / cand.tries, q, dof))


def same_signature(
    ev: StaticEvidence, K: FloatArray, X: FloatArray, a: Candidate, b: Candidate, th: Thresholds
) -> bool:
    """Whether every column of ``a`` lies in ``b``'s span beyond X, to |cos| > 1 − ``th.alias_tol``."""
    if a is b:
        return True
    Qx, _ = np.linalg.qr(X)
    A, B = a.columns(ev, K), b.columns(ev, K)
    A, B = A - Qx @ (Qx.T @ A), B - Qx @ (Qx.T @ B)
    Qb, _ = np.linalg.qr(B)
    na = np.maximum(np.linalg.norm(A, axis=0), 1e-300)
    return bool(np.all(np.linalg.norm(Qb.T @ A, axis=0) / na > 1.0 - th.alias_tol))
