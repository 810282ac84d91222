"""The model during selection: its candidates, noise and fit, and the statistics of adding a
column to it.

A model is the first-order design (bias and K, ``effects.first_order_design``) with the
candidates' columns appended, fitted by GLS under the recording's noise (window scatter and
slow wander by REML, ``likelihood.fit_noise``; the pose error as a variance component).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from bench.diagnosis.effects import Candidate, first_order_design, pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import GlsFit, NoiseParams, fit_noise, gls, window_covariance
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.diagnosis.wander_cap import SlowNoiseCap

POSE_ERROR = "pose_error"
"""The effect of the pose error, the selection's variance component (``ModelState.pose``)."""


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
    """The current model during selection.

    :param swapped: catalogue effects replaced by library terms (not tried again);
        :param excluded: effects taken out by a check after the selection (catalogue effects,
        library terms; ``greedy.resume``: not candidates from the step before they entered).
    """

    candidates: list[Candidate] = field(default_factory=list)
    pose: bool = False
    noise: NoiseParams | None = None
    fit: GlsFit | None = None
    steps: list[Step] = field(default_factory=list)
    pose_edf: float = 0.0
    swapped: set[str] = field(default_factory=set)
    excluded: frozenset[str] = frozenset()

    def holds(self, cand: Candidate) -> bool:
        """Whether ``cand`` is in the model (a family: a candidate it was resolved into, same label)."""
        if cand.family is not None:
            return any(c.label == cand.label for c in self.candidates)
        return cand in self.candidates

    def copy(self) -> ModelState:
        """A copy whose lists and sets can change without changing this state."""
        return replace(
            self, candidates=list(self.candidates), steps=list(self.steps), swapped=set(self.swapped)
        )


def design(ev: StaticEvidence, K: FloatArray, cands: list[Candidate]) -> FloatArray:
    """(3m, 12 + Σq) first-order design with the candidates' columns appended."""
    X = first_order_design(ev.f_m_s2)
    return np.hstack([X] + [c.columns(ev, K) for c in cands]) if cands else X


def scale_matrix(fit: GlsFit) -> FloatArray:
    """K (3, 3) from the first 12 coefficients."""
    return fit.theta[3:12].reshape(3, 3)


def scale_matrix_of(state: ModelState) -> FloatArray:
    """K (3, 3) of the state's fit."""
    assert state.fit is not None
    return scale_matrix(state.fit)


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
    th: Thresholds = THRESHOLDS,
    excess: FloatArray | None = None,
) -> tuple[NoiseParams, GlsFit, FloatArray]:
    """REML noise and GLS fit of a model, the columns evaluated at K0 (then at the fitted K).

    ``cap`` is the recording's slow-noise bound (``wander_cap``), built here at
    ``th.cap_alpha`` if not given.
    The slow noise has one level scaled by the channels' gains, or with ``own`` one level
    per channel. Each channel's own excess ε_c² (``likelihood.NoiseParams.excess_var``) is
    re-estimated where ``init`` holds one as a free parameter, or on the channels where
    ``excess`` (3,) (channel units², the start) is positive.
    """
    cap = SlowNoiseCap(ev, th.cap_alpha) if cap is None else cap
    K = K0
    noise: NoiseParams | None = init
    fit: GlsFit | None = None
    z = ev.y.reshape(-1)
    for it in range(iterations):
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
            near_init=True,
            excess_start=excess if it == 0 else None,
        )
        K = scale_matrix(fit)
    assert noise is not None and fit is not None
    return noise, fit, K


def lr_fixed(
    ev: StaticEvidence,
    X0: FloatArray,
    X1: FloatArray,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
) -> float:
    C = window_covariance(ev.V, ev.mid_s, noise, pose_response(ev, K), fixed)
    return gls(X0, ev.y.reshape(-1), C).chi2 - gls(X1, ev.y.reshape(-1), C).chi2


def whitened_lr(
    ev: StaticEvidence,
    X: FloatArray,
    cols: FloatArray,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
) -> tuple[FloatArray, FloatArray]:
    """Δχ² of adding each column of ``cols`` (3m, N) alone to X under the current noise, and the
    fraction of each whitened column outside the whitened span of X (its leverage)."""
    # GLS with C⁻¹ applied in O(m) (``window_covariance``): for a column a, with P the
    # residual-maker C⁻¹ − C⁻¹X (XᵀC⁻¹X)⁻¹ XᵀC⁻¹, Δχ² = (aᵀPy)² / aᵀPa and the leverage is
    # sqrt(aᵀPa / aᵀC⁻¹a) (the whitened column's share outside the whitened span of X).
    solver = window_covariance(ev.V, ev.mid_s, noise, pose_response(ev, K), fixed).factor()
    y = ev.y.reshape(-1)
    Ci_X, Ci_y, Ci_A = solver.solve(X), solver.solve(y), solver.solve(cols)
    M = X.T @ Ci_X
    b_y = np.linalg.solve(M, X.T @ Ci_y)
    XtCiA = X.T @ Ci_A
    aPy = cols.T @ Ci_y - XtCiA.T @ b_y
    aCa = np.sum(cols * Ci_A, axis=0)
    aPa = np.maximum(aCa - np.sum(XtCiA * np.linalg.solve(M, XtCiA), axis=0), 0.0)
    lev = np.sqrt(aPa / np.maximum(aCa, 1e-300))
    lr = aPy**2 / np.maximum(aPa, 1e-300)
    return lr, lev


def bic(ev: StaticEvidence, state: ModelState) -> float:
    """BIC −2 ℓ_ML + k ln n of the model: k its coefficients, free noise parameters and the pose variance."""
    assert state.fit is not None and state.noise is not None
    k = state.fit.theta.size + state.noise.n_free + (1 if state.pose else 0)
    k += sum(c.extra_params for c in state.candidates)
    return -2.0 * state.fit.loglik_ml + k * math.log(ev.n_obs)
