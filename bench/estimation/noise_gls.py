"""Generalised least squares of a noise model on an Allan curve: the machinery of
:mod:`bench.estimation.noise_terms` (see its module doc for the model and the choices).

:func:`gls`: iterated non-negative GLS with the overlapping estimates' covariance from the
model's spectrum and an optional model allowance; :func:`allowance`: that allowance's level
and correlation length; :func:`term_variances`: the sigmas (normal matrix or sandwich);
:func:`select_terms`: which of quantisation and rate ramp the curve needs.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.optimize import nnls

from bench.estimation.allan_covariance import (
    allan_correlation,
    allowance_correlation,
    cholesky_ridged,
    forward_solve,
)

FloatArray = npt.NDArray[np.float64]

BI_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
"""0.6643: Allan deviation of the bias-instability floor per unit B (IEEE 952 Table C.2)."""

MISFIT_LEVEL = 0.95
"""χ² above this quantile of its distribution counts as model misfit (see :func:`fit_noise_model_curve`)."""

ALLOWANCE_LENGTHS_OCTAVES = (0.0, 1.0, 4.0, 16.0)
"""Candidate correlation lengths of the model allowance along τ (octaves; 0: independent points).

Those longer than the fitted τ range are dropped; the one of highest likelihood is used
(:func:`_allowance`).
"""


def basis(taus_s: npt.ArrayLike) -> FloatArray:
    """(m, 5) Allan variance per unit squared coefficient: 3/τ², 1/τ, 0.664², τ/3, τ²/2."""
    t = np.asarray(taus_s, dtype=float)
    return np.stack([3.0 / t**2, 1.0 / t, np.full_like(t, BI_FACTOR**2), t / 3.0, t**2 / 2.0], axis=1)


class GlsFit(NamedTuple):
    """One iterated GLS fit (:func:`_gls`); the covariance parts are those of its final model."""

    chi2: float
    dof: int
    p: FloatArray
    As: FloatArray
    """(m, k) whitened design L⁻¹A."""
    L: FloatArray
    """(m, m) Cholesky factor of the covariance C used."""
    stat_cov: FloatArray
    """(m, m) D·R·D, the sampling covariance of σ̂² under the final model."""
    model: FloatArray
    """(m,) the final model's Allan variance."""

    @property
    def logdet(self) -> float:
        """ln det C."""
        return 2.0 * float(np.sum(np.log(np.diag(self.L))))


def gls(
    t: FloatArray,
    s2: FloatArray,
    nu: FloatArray,
    A: FloatArray,
    active: list[int],
    tau0_s: float,
    floor_rel: float,
    n_iterations: int,
    floor_octaves: float = 0.0,
) -> GlsFit:
    """Iterated non-negative GLS of s2 on A (k columns), non-negative coefficients p (k,).

    Covariance of σ̂²: C = D·R·D + F·R_F·F, D = diag(σ²·√(2/edf)), F = diag(2·floor_rel·σ²),
    with σ² the current model, R from :func:`allan_correlation` of the current model and R_F
    from :func:`allowance_correlation` with length floor_octaves.
    """
    model = np.maximum(s2, np.max(s2) * 1e-300)
    Ar = A / model[:, None]
    col = np.maximum(np.linalg.norm(Ar, axis=0), np.finfo(float).tiny)
    p = nnls(Ar / col, np.ones(t.size))[0] / col  # start: relative least squares
    p_full = np.zeros(5)
    p_full[active] = p
    corr_floor = allowance_correlation(t, floor_octaves)
    for it in range(n_iterations + 1):
        corr = allan_correlation(t, p_full, tau0_s)
        d = model * np.sqrt(2.0 / nu)
        fl = 2.0 * floor_rel * model
        stat_cov = corr * d[:, None] * d[None, :]
        L = cholesky_ridged(stat_cov + corr_floor * fl[:, None] * fl[None, :])
        white = forward_solve(L, np.column_stack([A, s2]))
        As, s2w = white[:, :-1], white[:, -1]
        if it == n_iterations:
            break
        scale = np.linalg.norm(As, axis=0)
        p_scaled, _ = nnls(As / scale, s2w)
        p = p_scaled / scale
        p_full = np.zeros(5)
        p_full[active] = p
        model = np.maximum(A @ p, np.max(s2) * 1e-12)
    r = s2w - As @ p
    dof = max(t.size - int(np.count_nonzero(p > 0)), 1)
    return GlsFit(float(r @ r), dof, p, As, L, stat_cov, model)


def floor_for_unit_chi2(
    t: FloatArray,
    s2: FloatArray,
    nu: FloatArray,
    A: FloatArray,
    active: list[int],
    tau0_s: float,
    n_it: int,
    floor_octaves: float,
) -> float:
    """Relative model allowance on σ (0.1 % … 50 %) at which the fit's χ²/dof is 1, by bisection in log.

    Seven halvings of ln(500): the level to ±5 %; two re-weighting passes per trial.
    """
    lo, hi = math.log(1e-3), math.log(0.5)
    for _ in range(7):
        mid = 0.5 * (lo + hi)
        g = gls(t, s2, nu, A, active, tau0_s, math.exp(mid), min(n_it, 2), floor_octaves)
        lo, hi = (mid, hi) if g.chi2 / g.dof > 1.0 else (lo, mid)
    return math.exp(hi)


def allowance(
    t: FloatArray, s2: FloatArray, nu: FloatArray, A: FloatArray, active: list[int], tau0_s: float, n_it: int
) -> tuple[float, float, float]:
    """(floor_rel, length in octaves, floor_rel at length 0) of the model allowance.

    For each length of :data:`ALLOWANCE_LENGTHS_OCTAVES` within the fitted τ range, the level
    giving χ²/dof = 1; of those, the pair of highest Gaussian likelihood (smallest
    χ² + ln det C); and the level for independent points (length 0), which the values use.
    """
    span_octaves = float(np.log2(t.max() / t.min()))
    best = (math.inf, 0.0, 0.0)
    independent = math.nan
    for length in ALLOWANCE_LENGTHS_OCTAVES:
        if length > span_octaves:
            break
        floor = floor_for_unit_chi2(t, s2, nu, A, active, tau0_s, n_it, length)
        independent = floor if length == 0.0 else independent
        g = gls(t, s2, nu, A, active, tau0_s, floor, min(n_it, 2), length)
        if g.chi2 + g.logdet < best[0]:
            best = (g.chi2 + g.logdet, floor, length)
    return best[1], best[2], independent


def term_variances(fit: GlsFit, inflate: float, cov: FloatArray | None = None) -> FloatArray:
    """(k,) variances of the squared coefficients of a GLS fit, times inflate.

    ``cov`` None: diag (AsᵀAs)⁻¹, As the whitened design. Otherwise the sandwich for data of
    covariance ``cov`` (m, m) fitted with the fit's own weights: H⁻¹·Asᵀ(L⁻¹·cov·L⁻ᵀ)As·H⁻¹,
    H = AsᵀAs (White, Econometrica 48, 1980). The normal matrix holds every fitted term, also
    one the non-negativity bound set to 0: the others still trade with it; which terms are
    fitted is :func:`select_terms`'s choice (``noise_terms`` module doc).
    """
    H_inv = np.linalg.pinv(fit.As.T @ fit.As)
    if cov is None:
        return np.asarray(np.diag(H_inv) * inflate, dtype=float)
    half = forward_solve(fit.L, cov)  # L⁻¹·cov
    meat = forward_solve(fit.L, np.ascontiguousarray(half.T))  # L⁻¹·cov·L⁻ᵀ (cov symmetric)
    return np.asarray(np.diag(H_inv @ fit.As.T @ meat @ fit.As @ H_inv) * inflate, dtype=float)


SELECT_DELTA_CHI2 = 5.41
"""Q or R stays in the model when leaving it out raises χ² (per χ²/dof when above 1) by at least
this: the 1 % point of ½χ²₀ + ½χ²₁, the likelihood ratio of a parameter on its bound
(Self & Liang 1987), i.e. the 98 % point of χ²₁."""

OPTIONAL_TERMS = (0, 4)
"""Quantisation and rate ramp: in the model only where the curve needs them (:func:`select_terms`)."""


def select_terms(
    t: FloatArray, s2: FloatArray, nu: FloatArray, active: list[int], tau0_s: float, n_it: int, fit: GlsFit
) -> list[int]:
    """Indices (Q, N, B, K, R = 0 … 4, the columns of :func:`basis`) of the terms to fit:
    ``active`` less the optional ones (:data:`OPTIONAL_TERMS`) whose removal raises χ² by
    less than :data:`SELECT_DELTA_CHI2`,
    removed one at a time, smallest rise first (backward elimination). ``fit``: the GLS of all
    of ``active`` without allowance; every trial refit is one too.
    """
    chosen = list(active)
    while True:
        scale = max(1.0, fit.chi2 / fit.dof)
        trials = []
        for idx in chosen:
            if idx not in OPTIONAL_TERMS or len(chosen) == 1:
                continue
            rest = [i for i in chosen if i != idx]
            g = gls(t, s2, nu, basis(t)[:, rest], rest, tau0_s, 0.0, n_it)
            trials.append(((g.chi2 - fit.chi2) / scale, idx, g))
        if not trials:
            return chosen
        delta, idx, g = min(trials, key=lambda x: x[0])
        if delta >= SELECT_DELTA_CHI2:
            return chosen
        chosen.remove(idx)
        fit = g
