"""Greedy forward selection of effects: a significance gate to admit, BIC to choose.

At each step every candidate not yet in the model is tried (fixed columns appended to the
design; the pose error as a variance component). A candidate is admitted only if

1. it is observable: its columns keep at least ``RELATIVE_LEVERAGE_MIN`` of their norm
   outside the span of the current design (else bias, K and the effects already in the
   model would absorb it: it is reported as indistinguishable, not guessed);
2. its statistic passes the gate at α = ``false_alarm`` / N (N candidates in the step).
   Fixed columns: LR = Δχ² = χ²_current − χ²_extended, both under the noise re-estimated
   (REML) under the extended model (the Wald statistic of the q new columns), must exceed
   q·F_{1−α}(q, n − p), p the extended design's columns (F rather than χ²_q because the
   noise level is estimated from the same n observations). The pose variance, a boundary
   parameter: LR = 2 Δℓ_REML against the 50:50 mixture of χ²_0 and χ²_1 (the χ²_1
   quantile at 2α);
3. its BIC change Δ = −LR + q ln n is negative.

Among the admissible candidates the one with the lowest BIC change enters; selection stops
when none is admissible. Candidates are ranked first with the current noise held fixed
and only the best ``SHORTLIST`` are re-fitted with their own noise (the REML fit is the
expensive part).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2 as chi2_dist
from scipy.stats import f as f_dist

from bench.diagnosis.effects import Candidate, first_order_design, leverage, pose_response
from bench.diagnosis.effects.base import RELATIVE_LEVERAGE_MIN, FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import GlsFit, NoiseParams, fit_noise, gls, window_covariance
from bench.diagnosis.wander_cap import SlowNoiseCap

FALSE_ALARM = 0.01
"""False-alarm probability of one selection step: split evenly (Bonferroni) over the
candidates tried in that step, so each gate runs at FALSE_ALARM / N."""
SHORTLIST = 4
MAX_STEPS = 8


WANDER_LIKE = ("bias_drift", "temperature_bias")
"""Effects whose signature a slow bias wander can imitate (a trend in time, or in a temperature
that follows time). With such an effect in the model, REML can let the wander collapse to
nothing (a 12-window run holds one or two correlation times of wander, whose trend the
effect then takes), and the Wald statistic under that noise compares the trend with white
noise instead of with the wander the recording shows. Such a claim must also pass the full
likelihood ratio 2 (ℓ_ML,with − ℓ_ML,without) in which each channel's own slow wander
(level and correlation time, REML) is re-estimated in both models: the wander the recording
shows without the effect competes with it, and the smaller statistic counts."""


def wander_note(effect: str, lr: float, lr_wander: float, gate: float, noise: NoiseParams) -> str:
    """Why a wander-like effect was not admitted although it fits (``select``)."""
    tau = ", ".join(f"{np.sqrt(t):.2g}" for t in noise.tau2)
    corr = "" if noise.corr_time_s <= 0 else f", correlation time {noise.corr_time_s:.0f} s"
    what = "a drift" if effect == "bias_drift" else "a temperature coefficient"
    return (
        f"{what} fits (likelihood ratio {lr:.1f} with the wander it leaves), but the slow wander the "
        f"recording shows without it (sigma = [{tau}] channel units{corr}) makes such a trend too "
        f"(likelihood ratio {lr_wander:.1f} with each channel's wander re-estimated, gate {gate:.1f}): "
        "this recording cannot tell the effect from a wander; longer or repeated runs can"
    )


@dataclass(frozen=True)
class Step:
    """One admitted candidate: its label, effect, LR statistic, BIC change, dof."""

    label: str
    effect: str
    lr: float
    delta_bic: float
    q: int


@dataclass
class ModelState:
    """The current model during selection."""

    candidates: list[Candidate] = field(default_factory=list)
    pose: bool = False
    noise: NoiseParams | None = None
    fit: GlsFit | None = None
    steps: list[Step] = field(default_factory=list)


def design(ev: StaticEvidence, K: FloatArray, cands: list[Candidate]) -> FloatArray:
    """(3m, 12 + Σq) first-order design with the candidates' columns appended."""
    X = first_order_design(ev.f_m_s2)
    return np.hstack([X] + [c.columns(ev, K) for c in cands]) if cands else X


def scale_matrix(fit: GlsFit) -> FloatArray:
    """K (3, 3) from the first 12 coefficients."""
    return fit.theta[3:12].reshape(3, 3)


def fit_model(
    ev: StaticEvidence,
    cands: list[Candidate],
    pose: bool,
    K0: FloatArray,
    fixed: FloatArray | None,
    init: NoiseParams | None = None,
    iterations: int = 1,
    cap: SlowNoiseCap | None = None,
    own: bool = False,
) -> tuple[NoiseParams, GlsFit, FloatArray]:
    """REML noise and GLS fit of a model, the columns evaluated at K0 (then at the fitted K).

    ``cap`` is the recording's slow-noise bound (``wander_cap``), built here if not given.
    The slow noise has one level scaled by the channels' gains, or with ``own`` one level
    per channel.
    """
    cap = SlowNoiseCap(ev) if cap is None else cap
    K = K0
    noise: NoiseParams | None = init
    fit: GlsFit | None = None
    z = ev.y.reshape(-1)
    for _ in range(iterations):
        X = design(ev, K, cands)
        J = pose_response(ev, K)
        noise, fit = fit_noise(
            X,
            z,
            ev.V,
            ev.mid_s,
            J_pose=J,
            fixed=fixed,
            estimate_pose=pose,
            init=noise,
            channel_gain=None if own else np.sqrt(np.median(np.diagonal(ev.V, axis1=1, axis2=2), axis=0)),
            tau2_cap=cap,
        )
        K = scale_matrix(fit)
    assert noise is not None and fit is not None
    return noise, fit, K


def _lr_fixed(
    ev: StaticEvidence,
    X0: FloatArray,
    X1: FloatArray,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
) -> float:
    C = window_covariance(ev.V, ev.mid_s, noise, pose_response(ev, K), fixed)
    return gls(X0, ev.y.reshape(-1), C).chi2 - gls(X1, ev.y.reshape(-1), C).chi2


def select(
    ev: StaticEvidence,
    pool: list[Candidate],
    *,
    pose_allowed: bool,
    fixed: FloatArray | None = None,
    false_alarm: float = FALSE_ALARM,
) -> tuple[ModelState, dict[str, str]]:
    """Run the greedy selection.

    :param ev: the evidence.
    :param pool: observable candidates (fixed columns).
    :param pose_allowed: try the pose-error variance component.
    :param fixed: fixed extra covariance per window (orientation-free diagnosis).
    :returns: the final state and, per candidate label, why it was not admitted when it
        could not be told from the model (``"indistinguishable"`` notes).
    """
    n = ev.n_obs
    state = ModelState()
    X0 = first_order_design(ev.f_m_s2)
    K = np.asarray(np.linalg.lstsq(X0, ev.y.reshape(-1), rcond=None)[0][3:12], dtype=float).reshape(3, 3)
    cap = SlowNoiseCap(ev)
    state.noise, state.fit, K = fit_model(ev, [], False, K, fixed, iterations=2, cap=cap)
    notes: dict[str, str] = {}
    for _ in range(MAX_STEPS):
        assert state.noise is not None and state.fit is not None
        X = design(ev, K, state.candidates)
        n_tried = sum(1 for c in pool if c not in state.candidates) + (
            1 if pose_allowed and not state.pose else 0
        )
        alpha = false_alarm / max(n_tried, 1)
        admissible: list[tuple[float, Candidate | None, float, tuple[NoiseParams, GlsFit, FloatArray]]] = []
        ranked: list[tuple[float, Candidate]] = []
        for cand in pool:
            if cand in state.candidates:
                continue
            cols = cand.columns(ev, K)
            lev = leverage(X, cols)
            if np.any(lev < RELATIVE_LEVERAGE_MIN):
                notes[cand.label] = (
                    f"cannot be told apart from the model's other terms on this pose set "
                    f"(only {float(np.min(lev)):.1e} of its signature is independent of them)"
                )
                continue
            ranked.append((_lr_fixed(ev, X, np.hstack([X, cols]), state.noise, K, fixed), cand))
        ranked.sort(key=lambda r: -r[0])
        null_own: tuple[NoiseParams, GlsFit, FloatArray] | None = None
        for _lr0, cand in ranked[:SHORTLIST]:
            q = len(cand.names)
            model1 = fit_model(ev, [*state.candidates, cand], state.pose, K, fixed, state.noise, cap=cap)
            noise1, _fit1, K1 = model1
            X1 = design(ev, K1, [*state.candidates, cand])
            lr = _lr_fixed(ev, X1[:, : X.shape[1]], X1, noise1, K1, fixed)
            gate = q * float(f_dist.ppf(1.0 - alpha, q, n - X1.shape[1]))
            if cand.effect in WANDER_LIKE and lr > gate:
                # the claim must beat the trend the measured wander makes: the likelihood ratio
                # with each channel's own slow wander re-estimated in both models
                if null_own is None:
                    null_own = fit_model(
                        ev, state.candidates, state.pose, K, fixed, state.noise, cap=cap, own=True
                    )
                ext_own = fit_model(
                    ev, [*state.candidates, cand], state.pose, K, fixed, null_own[0], cap=cap, own=True
                )
                lr_wander = max(0.0, 2.0 * (ext_own[1].loglik_ml - null_own[1].loglik_ml))
                if lr_wander <= gate:
                    notes[cand.label] = wander_note(cand.effect, lr, lr_wander, gate, null_own[0])
                lr = min(lr, lr_wander)
            dbic = -lr + q * math.log(n)
            if lr > gate and dbic < 0:
                admissible.append((dbic, cand, lr, model1))
        if pose_allowed and not state.pose:
            noise1, fit1, K1 = fit_model(ev, state.candidates, True, K, fixed, state.noise, cap=cap)
            if noise1.pose_var_rad2 > 0:
                lr = 2.0 * (fit1.loglik_reml - state.fit.loglik_reml)
                dbic = -lr + math.log(n)
                if lr > float(chi2_dist.ppf(1.0 - 2.0 * alpha, 1)) and dbic < 0:
                    admissible.append((dbic, None, lr, (noise1, fit1, K1)))
        if not admissible:
            break
        dbic, chosen, lr, model1 = min(admissible, key=lambda a: a[0])
        if chosen is None:
            state.pose = True
            state.steps.append(Step("pose_error", "pose_error", lr, dbic, 1))
        else:
            state.candidates.append(chosen)
            state.steps.append(Step(chosen.label, chosen.effect, lr, dbic, len(chosen.names)))
        state.noise, state.fit, K = model1
    return state, notes
