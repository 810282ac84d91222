"""Generalised least squares of a noise model on an Allan curve: the machinery of
:mod:`bench.estimation.noise_terms` (see its module doc for the model and the choices).

:func:`gls`: iterated non-negative GLS with the overlapping estimates' covariance from the
model's spectrum and an optional model allowance; :func:`allowance`: that allowance's level
and correlation length; :func:`term_variances`: the sigmas (normal matrix or sandwich);
:func:`fit_terms`: that GLS with the Gauss–Markov T_c profiled; :func:`select_terms`: which of
quantisation and rate ramp the curve needs; :func:`select_with_gauss_markov`: those and the
Gauss–Markov term, by its own test against the model without it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar, nnls

from bench.estimation.allan_covariance import (
    allan_correlation,
    allowance_correlation,
    cholesky_ridged,
    forward_solve,
)
from bench.estimation.gauss_markov_allan import gm_basis, gm_basis_dlog_tc

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


GM = 5
"""Column of the Gauss–Markov term in :func:`basis` (its coefficient σ_gm², its T_c profiled)."""


def basis(taus_s: npt.ArrayLike, tc_s: float = math.nan) -> FloatArray:
    """(m, 6) Allan variance per unit squared coefficient: 3/τ², 1/τ, 0.664², τ/3, τ²/2, g(τ; T_c).

    g: the Gauss–Markov term of correlation time tc_s (s) per unit σ_gm²
    (:func:`~bench.estimation.gauss_markov_allan.gm_basis`); zeros when tc_s is NaN.
    """
    t = np.asarray(taus_s, dtype=float)
    g = gm_basis(t, tc_s) if math.isfinite(tc_s) else np.zeros_like(t)
    return np.stack([3.0 / t**2, 1.0 / t, np.full_like(t, BI_FACTOR**2), t / 3.0, t**2 / 2.0, g], axis=1)


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
    tc_s: float = math.nan
    """Gauss–Markov correlation time of the fit (s); NaN without that term."""
    dtc: FloatArray | None = None
    """(m,) whitened ∂model/∂ln T_c when the Gauss–Markov term is fitted and > 0, else None."""

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
    tc_s: float = math.nan,
) -> GlsFit:
    """Iterated non-negative GLS of s2 on A (k columns), non-negative coefficients p (k,).

    Covariance of σ̂²: C = D·R·D + F·R_F·F, D = diag(σ²·√(2/edf)), F = diag(2·floor_rel·σ²),
    with σ² the current model, R from :func:`allan_correlation` of the current model and R_F
    from :func:`allowance_correlation` with length floor_octaves. ``active`` names the
    columns of :func:`basis` in A; when it holds :data:`GM`, tc_s is that term's T_c (s),
    held fixed here (:func:`fit_terms` profiles it) and counted as a fitted parameter.
    """
    model = np.maximum(s2, np.max(s2) * 1e-300)
    Ar = A / model[:, None]
    col = np.maximum(np.linalg.norm(Ar, axis=0), np.finfo(float).tiny)
    p = nnls(Ar / col, np.ones(t.size))[0] / col  # start: relative least squares
    p_full = np.zeros(6)
    p_full[active] = p
    corr_floor = allowance_correlation(t, floor_octaves)
    for it in range(n_iterations + 1):
        corr = allan_correlation(t, p_full, tau0_s, tc_s)
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
        p_full = np.zeros(6)
        p_full[active] = p
        model = np.maximum(A @ p, np.max(s2) * 1e-12)
    r = s2w - As @ p
    gm_on = GM in active and p_full[GM] > 0.0 and math.isfinite(tc_s)
    dof = max(t.size - int(np.count_nonzero(p > 0)) - int(gm_on), 1)
    dtc = forward_solve(L, (p_full[GM] * gm_basis_dlog_tc(t, tc_s))[:, None])[:, 0] if gm_on else None
    return GlsFit(float(r @ r), dof, p, As, L, stat_cov, model, tc_s if GM in active else math.nan, dtc)


TC_GRID_PER_OCTAVE = 2
"""Profile of the Gauss–Markov T_c: trial values this many per octave over :func:`tc_range_s`,
then a bounded scalar search between the best one's neighbours (:func:`fit_terms`)."""


TC_MIN_OVER_TAU_MIN = 8.0
"""Shortest Gauss–Markov T_c fitted, in units of the curve's first τ (:func:`tc_range_s`)."""


def tc_range_s(t: FloatArray) -> tuple[float, float]:
    """(lo, hi) of the Gauss–Markov T_c a curve over τ in t (s) can show: 2 τ_min to τ_max / 4.

    The hump peaks at 1.89 T_c; an octave of its rise lies above τ_min and its peak an octave
    below τ_max. Outside, the term is a white noise (T_c ≪ τ: g → 2T_c/τ, N's column) or a rate
    random walk (T_c ≫ τ: g → 2τ/(3T_c), K's column), and the normal matrix degenerates.
    Empty (lo > hi) on a curve of fewer than 3 octaves.
    """
    return TC_MIN_OVER_TAU_MIN * float(t.min()), float(t.max()) / 4.0


def fit_terms(
    t: FloatArray,
    s2: FloatArray,
    nu: FloatArray,
    active: list[int],
    tau0_s: float,
    n_it: int,
    floor_rel: float = 0.0,
    floor_octaves: float = 0.0,
) -> GlsFit:
    """:func:`gls` of the columns ``active`` of :func:`basis`; with :data:`GM` among them, its
    T_c by profile: the T_c of least χ² (the Gaussian likelihood's profile at the GLS weights;
    trial fits with two re-weighting passes, the chosen one with n_it).
    """
    if GM not in active:
        return gls(t, s2, nu, basis(t)[:, active], active, tau0_s, floor_rel, n_it, floor_octaves)

    def chi2_at(log_tc: float, passes: int) -> float:
        tc = math.exp(log_tc)
        g = gls(t, s2, nu, basis(t, tc)[:, active], active, tau0_s, floor_rel, passes, floor_octaves, tc)
        return g.chi2

    lo_s, hi_s = tc_range_s(t)
    if lo_s > hi_s:
        raise ValueError(f"a Gauss–Markov term needs τ over 3 octaves, got {t.min():g} to {t.max():g} s")
    grid = np.arange(math.log(lo_s), math.log(hi_s) + 1e-9, math.log(2.0) / TC_GRID_PER_OCTAVE)
    trial = [chi2_at(float(x), min(n_it, 2)) for x in grid]
    i = int(np.argmin(trial))
    lo, hi = float(grid[max(i - 1, 0)]), float(grid[min(i + 1, grid.size - 1)])
    best = minimize_scalar(lambda x: chi2_at(x, min(n_it, 2)), bounds=(lo, hi), method="bounded",
                           options={"xatol": 0.01})  # fmt: skip
    log_tc = float(best.x) if best.fun < trial[i] else float(grid[i])
    tc = math.exp(log_tc)
    return gls(t, s2, nu, basis(t, tc)[:, active], active, tau0_s, floor_rel, n_it, floor_octaves, tc)


def floor_for_unit_chi2(
    t: FloatArray,
    s2: FloatArray,
    nu: FloatArray,
    A: FloatArray,
    active: list[int],
    tau0_s: float,
    n_it: int,
    floor_octaves: float,
    tc_s: float = math.nan,
) -> float:
    """Relative model allowance on σ (0.1 % … 50 %) at which the fit's χ²/dof is 1, by bisection in log.

    Seven halvings of ln(500): the level to ±5 %; two re-weighting passes per trial.
    """
    lo, hi = math.log(1e-3), math.log(0.5)
    for _ in range(7):
        mid = 0.5 * (lo + hi)
        g = gls(t, s2, nu, A, active, tau0_s, math.exp(mid), min(n_it, 2), floor_octaves, tc_s)
        lo, hi = (mid, hi) if g.chi2 / g.dof > 1.0 else (lo, mid)
    return math.exp(hi)


def allowance(
    t: FloatArray,
    s2: FloatArray,
    nu: FloatArray,
    A: FloatArray,
    active: list[int],
    tau0_s: float,
    n_it: int,
    tc_s: float = math.nan,
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
        floor = floor_for_unit_chi2(t, s2, nu, A, active, tau0_s, n_it, length, tc_s)
        independent = floor if length == 0.0 else independent
        g = gls(t, s2, nu, A, active, tau0_s, floor, min(n_it, 2), length, tc_s)
        if g.chi2 + g.logdet < best[0]:
            best = (g.chi2 + g.logdet, floor, length)
    return best[1], best[2], independent


def term_variances(fit: GlsFit, inflate: float, cov: FloatArray | None = None) -> FloatArray:
    """(k,) variances of the squared coefficients of a GLS fit, times inflate; (k + 1,) with the
    variance of ln T_c last when the fit has a Gauss–Markov term > 0 (``fit.dtc``: its column
    joins the whitened design, the linearised covariance of the profiled T_c and its trade).

    ``cov`` None: diag (AsᵀAs)⁻¹, As the whitened design. Otherwise the sandwich for data of
    covariance ``cov`` (m, m) fitted with the fit's own weights: H⁻¹·Asᵀ(L⁻¹·cov·L⁻ᵀ)As·H⁻¹,
    H = AsᵀAs (White, Econometrica 48, 1980). The normal matrix holds every fitted term, also
    one the non-negativity bound set to 0: the others still trade with it; which terms are
    fitted is :func:`select_terms`'s choice (``noise_terms`` module doc).
    """
    As = fit.As if fit.dtc is None else np.column_stack([fit.As, fit.dtc])
    col = 1.0 / np.maximum(np.linalg.norm(As, axis=0), np.finfo(float).tiny)  # columns of unlike units
    H_inv = col[:, None] * np.linalg.pinv((As * col).T @ (As * col)) * col[None, :]
    if cov is None:
        return np.asarray(np.diag(H_inv) * inflate, dtype=float)
    half = forward_solve(fit.L, cov)  # L⁻¹·cov
    meat = forward_solve(fit.L, np.ascontiguousarray(half.T))  # L⁻¹·cov·L⁻ᵀ (cov symmetric)
    return np.asarray(np.diag(H_inv @ As.T @ meat @ As @ H_inv) * inflate, dtype=float)


SELECT_DELTA_CHI2 = 5.41
"""Q, R or the Gauss–Markov term stays in the model when leaving it out raises χ² (per χ²/dof
when above 1) by at least this: the 1 % point of ½χ²₀ + ½χ²₁, the likelihood ratio of a parameter on its bound
(Self & Liang 1987), i.e. the 98 % point of χ²₁."""

OPTIONAL_TERMS = (0, 4, GM)
"""Quantisation, rate ramp and the Gauss–Markov term: in the model only where the curve needs
them (:func:`select_terms`)."""


def select_terms(
    t: FloatArray,
    s2: FloatArray,
    nu: FloatArray,
    active: list[int],
    tau0_s: float,
    n_it: int,
    fit: GlsFit,
    optional: tuple[int, ...] = OPTIONAL_TERMS,
) -> list[int]:
    """Indices (Q, N, B, K, R, GM = 0 … 5, the columns of :func:`basis`) of the terms to fit:
    ``active`` less those of ``optional`` whose removal raises χ² (per χ²/dof when above 1) by
    less than :data:`SELECT_DELTA_CHI2`,
    removed one at a time, smallest rise first (backward elimination). ``fit``: the GLS of all
    of ``active`` without allowance (:func:`fit_terms`); every trial refit is one too, with
    the Gauss–Markov T_c profiled again where that term remains.
    """
    chosen = list(active)
    while True:
        scale = max(1.0, fit.chi2 / fit.dof)
        trials = []
        for idx in chosen:
            if idx not in optional or len(chosen) == 1:
                continue
            rest = [i for i in chosen if i != idx]
            g = fit_terms(t, s2, nu, rest, tau0_s, n_it)
            trials.append(((g.chi2 - fit.chi2) / scale, idx, g))
        if not trials:
            return chosen
        delta, idx, g = min(trials, key=lambda x: x[0])
        if delta >= SELECT_DELTA_CHI2:
            return chosen
        chosen.remove(idx)
        fit = g


POWER_LAW_OPTIONAL = (0, 4)
"""Quantisation and rate ramp: the optional power-law terms (:func:`select_with_gauss_markov`)."""


def select_with_gauss_markov(
    t: FloatArray,
    s2: FloatArray,
    nu: FloatArray,
    active: list[int],
    tau0_s: float,
    n_it: int,
    full: GlsFit,
    holds: bool,
) -> list[int]:
    """Terms to fit (indices as :func:`select_terms`) where ``active`` holds :data:`GM`.

    1. The power-law model the curve needs without the Gauss–Markov term: Q and R by
       :func:`select_terms`, or both kept where ``holds`` is False (the full model's χ²
       failed, so the bounded law does not hold).
    2. The Gauss–Markov term is one test against that model, also where χ² fails: it enters
       when adding it lowers χ² by at least :data:`SELECT_DELTA_CHI2` (per χ²/dof of the
       larger fit when above 1; T_c profiled, so the statistic is the maximum over T_c).
    3. With the term in, Q and R are chosen again beside it (:func:`select_terms` from
       ``full``, the fit of all of ``active``, the term held in).

    One test for the term, against the model without it: in a backward elimination from the
    full model it also stayed where χ² failed (every term kept) and where Q or R stayed
    beside it, 7 % of curves without a wander (docs/noise-model.md).
    """
    power_law = [i for i in active if i != GM]
    if holds:
        base = select_terms(t, s2, nu, power_law, tau0_s, n_it, fit_terms(t, s2, nu, power_law, tau0_s, n_it),
                            POWER_LAW_OPTIONAL)  # fmt: skip
    else:
        base = power_law
    without = fit_terms(t, s2, nu, base, tau0_s, n_it)
    with_gm = fit_terms(t, s2, nu, sorted([*base, GM]), tau0_s, n_it)
    delta = (without.chi2 - with_gm.chi2) / max(1.0, with_gm.chi2 / with_gm.dof)
    if delta < SELECT_DELTA_CHI2 or with_gm.dtc is None:
        return base
    return select_terms(t, s2, nu, active, tau0_s, n_it, full, POWER_LAW_OPTIONAL) if holds else list(active)
