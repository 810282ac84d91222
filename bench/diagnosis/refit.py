"""Refit with the chosen effects: the model sequence, parameters with sigmas, residuals before/after.

Every model of the sequence (first order, then each finding's effect added in the order
selection admitted it) is evaluated under one covariance, the final model's noise
(``likelihood.covariance``; the pose-error variance only in models that contain it), so
that χ², BIC and their changes compare like with like. Residuals of a model with the pose
error subtract each window's predicted pose offset J_w p̂_w, with (Harville 1977, BLUP)

    p̂_w = σ_p² J_wᵀ (P z)_w,   Cov(p_w | z) = σ_p² I − σ_p⁴ J_wᵀ P_ww J_w,
    P = C⁻¹ − C⁻¹ X (Xᵀ C⁻¹ X)⁻¹ Xᵀ C⁻¹.

Degrees of freedom of χ²/dof (:func:`residual_dof`): n − p for known orientations (n = 3m
stacked window means, p = 12 + the effects' coefficients). Without known orientations each
window's direction is taken from its own reading (two angles per window, given a wide
prior), so only its magnitude is evidence: m magnitudes against the scalar fit's 9
parameters (bias 3, lower-triangular L 6; K's 3 rotation angles are not seen) plus the
effects' coefficients, dof = m − 9 − (p − 12) = n − p − 2m + 3 (as ``scalar_fit``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.diagnosis.effects import Candidate, pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import GlsFit, NoiseParams, gls, window_covariance, without_pose
from bench.diagnosis.model_state import design


@dataclass(frozen=True)
class ModelFit:
    """One model of the sequence under the common covariance."""

    effects: tuple[str, ...]
    candidates: tuple[Candidate, ...]
    pose: bool
    fit: GlsFit
    resid: FloatArray  # (m, 3), pose offsets removed
    sigma: FloatArray  # (m, 3) noise sigma of each window mean (pose variance excluded)
    chi2_dof: float
    bic: float
    pose_angles: FloatArray | None  # (m, 2)
    pose_sigma: FloatArray | None  # (m, 2)


def residual_dof(ev: StaticEvidence, p: int) -> int:
    """Degrees of freedom of a model with ``p`` coefficients (module docstring), at least 1."""
    n = ev.n_obs
    dof = n - p if ev.orientation_known else n - p - 2 * ev.m + 3
    return max(dof, 1)


def evaluate(
    ev: StaticEvidence,
    cands: list[Candidate],
    pose: bool,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
) -> ModelFit:
    """GLS of one model under ``noise`` (pose variance kept only if ``pose``)."""
    nz = noise if pose else without_pose(noise)
    J = pose_response(ev, K)
    C = window_covariance(ev.V, ev.mid_s, nz, J, fixed)
    X = design(ev, K, cands)
    z = ev.y.reshape(-1)
    fit = gls(X, z, C)
    n, p = X.shape
    resid = fit.resid.copy()
    angles = angle_sigma = None
    if pose and nz.pose_var_rad2 > 0:
        fac = C.factor()
        Ci_r = fac.solve(fit.resid)
        CiX = fac.solve(X).reshape(ev.m, 3, p)
        s2 = nz.pose_var_rad2
        angles = np.einsum("wik,wi->wk", J, Ci_r.reshape(-1, 3)) * s2
        # diagonal blocks of P = C⁻¹ − C⁻¹X Cov(θ̂) XᵀC⁻¹, O(m)
        Pd = fac.inverse_diagonal_blocks() - np.einsum("wia,ab,wjb->wij", CiX, fit.cov, CiX)
        post = s2 * np.eye(2)[None] - s2 * s2 * np.einsum("wik,wij,wjl->wkl", J, Pd, J)
        angle_sigma = np.sqrt(np.clip(np.diagonal(post, axis1=1, axis2=2), 0.0, None))
        resid = resid - np.einsum("wik,wk->wi", J, angles).reshape(-1)
    base = window_covariance(ev.V, ev.mid_s, without_pose(nz), J, fixed)
    sigma = np.sqrt(base.diagonal()).reshape(-1, 3)
    k = p + nz.n_free + (1 if pose else 0) + sum(c.extra_params for c in cands)
    bic = -2.0 * fit.loglik_ml + k * math.log(n)
    effects = tuple(dict.fromkeys([c.effect for c in cands] + (["pose_error"] if pose else [])))
    return ModelFit(
        effects=effects,
        candidates=tuple(cands),
        pose=pose,
        fit=fit,
        resid=resid.reshape(-1, 3),
        sigma=sigma,
        chi2_dof=fit.chi2 / residual_dof(ev, p),
        bic=bic,
        pose_angles=angles,
        pose_sigma=angle_sigma,
    )


def model_sequence(
    ev: StaticEvidence,
    order: list[str],
    cands: list[Candidate],
    pose: bool,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
) -> list[ModelFit]:
    """First-order model, then each effect of ``order`` added in turn (all its candidates at once)."""
    out = [evaluate(ev, [], False, noise, K, fixed)]
    chosen: list[Candidate] = []
    with_pose = False
    for effect in order:
        if effect == "pose_error":
            with_pose = True
        else:
            chosen = chosen + [c for c in cands if c.effect == effect]
        out.append(evaluate(ev, chosen, with_pose and pose, noise, K, fixed))
    return out


def effect_parameters(
    model: ModelFit, effect: str, K: FloatArray
) -> tuple[dict[str, object], dict[str, object]]:
    """Contract parameters and sigmas of one effect in ``model`` (its candidates summed)."""
    values: dict[str, object] = {}
    sigmas: dict[str, object] = {}
    col = 12
    for c in model.candidates:
        q = len(c.names)
        if c.effect == effect:
            v, s = c.to_parameters(
                model.fit.theta[col : col + q], model.fit.cov[col : col + q, col : col + q], K
            )
            for name in v:
                values[name] = _add(values.get(name), v[name])
                sigmas[name] = _add_sigma(sigmas.get(name), s[name])
        col += q
    return values, sigmas


def _add(a: object, b: object) -> object:
    if a is None:
        return b
    return (np.asarray(a, dtype=float) + np.asarray(b, dtype=float)).tolist()


def _add_sigma(a: object, b: object) -> object:
    if a is None:
        return b
    return np.hypot(np.asarray(a, dtype=float), np.asarray(b, dtype=float)).tolist()
