"""Noise terms of an inertial sensor from its Allan curve (IEEE Std 952-1997 Annex C).

The standard noise model adds independent power-law processes; their Allan variances add
(IEEE 952 Table C.2, with u the unit of the rate data, e.g. m/s² for an accelerometer):

    σ²(τ) = 3Q²/τ²  +  N²/τ  +  (0.664·B)²  +  K²τ/3  +  R²τ²/2

    Q  quantisation noise                  (u·s)
    N  white noise / velocity random walk  (u·√s = u/√Hz), read at τ = 1 s on the −1/2 line
    B  bias instability                    (u),   flat floor σ = √(2 ln 2 / π)·B = 0.664·B
    K  rate random walk                    (u/√s), read at τ = 3 s on the +1/2 line
    R  rate ramp (drift)                   (u/s)

and, where the curve needs it, a first-order Gauss–Markov bias of level σ_gm (u) and
correlation time T_c (s), σ_gm²·g(τ; T_c) (:mod:`bench.estimation.gauss_markov_allan`): the
hump near T_c that a wandering bias makes and no power law follows.

:func:`fit_noise_model` fits the five squared coefficients p = [Q², N², B², K², R²] ≥ 0 by
non-negative generalised least squares on σ̂². The covariance of the σ̂² vector is
C = D·R·D: D = σ²(τ)·√(2/edf) (a χ² variable with edf degrees of freedom, SP1065 §5.3) and
R the correlation of overlapping estimates at different τ, computed from the model's own
spectrum (:func:`allan_correlation`; octave neighbours correlate 0.5 for white noise, 0.88
for rate random walk, and the correlation reaches several octaves). Both are iterated with
the fitted model. Treating the points as independent, or as an AR(1) chain along τ, made
the B and K sigmas 20-35 % too small. Real sensors' filters and non-power-law processes
depart from the model: when χ² exceeds its 95 % quantile, a relative allowance on σ
(``model_floor_rel``) is added to every point, set so that χ²/dof = 1. Without it the
points at short τ, whose edf run to 10⁵, would decide every term. Points before the curve's
first maximum are left out when the curve *rises* from τ0 (a sensor low-pass filter
correlates neighbouring samples; no term of the model rises at short τ).

The values come from the GLS with the allowance independent between τ. A misfit is smooth
in τ, though, so for the sigmas the allowance is a Gaussian process along log τ
(:func:`allowance_correlation`, exponential correlation of ``model_floor_corr_octaves``; the
model discrepancy of Kennedy & O'Hagan 2001), its length the most likely of
:data:`ALLOWANCE_LENGTHS_OCTAVES` and its level again χ²/dof = 1; the sigmas are the
sandwich of the values' GLS under that covariance (:func:`term_variances`), never smaller
than those of the fit without allowance scaled by its χ²/dof. Independent, the allowance
averaged down over the many short-τ points as if it were noise: on the imu_utils curves
(docs/noise-model.md) the 5-term N sigma was 1-2 % while two readings of one curve differed
by up to 17 %.

Which terms: N, B and K are always in the model, and their sigmas come from the normal
matrix of all three, also one the non-negativity bound set to 0 (it still trades with the
others). Quantisation Q, rate ramp R and the Gauss–Markov term enter only where the curve
needs them
(:func:`select_terms`): backward elimination, a term leaving when that raises χ² by less
than :data:`SELECT_DELTA_CHI2`, the 1 % point of the ½χ²₀ + ½χ²₁ law of a likelihood ratio
for a parameter on its bound (Self & Liang, JASA 82, 1987). That law needs the model to
hold: where χ² fails (above), Q and R stay. A term left out reads 0 with its one-sigma
upper limit from the full model. Counting the trade with a Q or R held at 0 by the bound
made every sigma too wide on short records, where the estimates cannot follow that trade
(they stay on the bound): between recordings of one sensor pair z 0.47-0.73 at 600 s, also
for a sensor of pure power laws (docs/noise-model.md); with the selection 0.78-1.02.
The Gauss–Markov term is one such test against the power-law model chosen without it, also
where χ² fails (per χ²/dof then; :func:`~bench.estimation.noise_gls.select_with_gauss_markov`):
kept by the gate or beside Q or R in the elimination, it entered 7 % of curves without a wander.
Its T_c is profiled (the T_c of least χ², :func:`~bench.estimation.noise_gls.fit_terms`)
in every fit that holds the term, the test's included; its sigma, and its trade with the
other terms, from the fit's design with the column ∂σ²/∂ln T_c added (linearised).

:func:`slope_method` is the graphical reading of Annex C: N from the points on the −1/2
line (read at τ = 1 s), K from the points on the +1/2 line (read at τ = 3 s), B from the
curve's minimum / 0.664. Its sigmas count the correlation of the overlapping estimates
between τ, the 5-term fit's model allowance as an error common to a line, and the points'
scatter about the line (docs/noise-model.md has the spread between recordings).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import stats

from bench.estimation.allan import AllanResult
from bench.estimation.allan_covariance import (
    allan_correlation,
    allowance_correlation,
    cholesky_ridged,
    forward_solve,
)
from bench.estimation.noise_gls import BI_FACTOR as BI_FACTOR
from bench.estimation.noise_gls import (
    GM,
    MISFIT_LEVEL,
    allowance,
    fit_terms,
    floor_for_unit_chi2,
    gls,
    select_terms,
    select_with_gauss_markov,
    tc_range_s,
    term_variances,
)
from bench.estimation.noise_gls import basis as basis

FloatArray = npt.NDArray[np.float64]

TERMS = ("quantization", "white", "bias_instability", "rate_random_walk", "rate_ramp", "gauss_markov")
"""Term names, in the order of :func:`basis`."""

DOMINANT_SHARE = 0.8
"""Slope method: a point belongs to a term's line where that term is ≥ 80 % of the model variance."""


@dataclass(frozen=True)
class NoiseTerms:
    """Noise coefficients of one channel, in the unit u of the Allan curve (see module doc).

    A ``*_sigma`` is one standard uncertainty. A term the fit set to zero has value 0 and
    its sigma is a one-sigma upper limit. NaN marks a term the method does not estimate.
    """

    quantization_q: float
    white_n: float
    bias_instability_b: float
    rate_random_walk_k: float
    rate_ramp_r: float
    quantization_q_sigma: float
    white_n_sigma: float
    bias_instability_b_sigma: float
    rate_random_walk_k_sigma: float
    rate_ramp_r_sigma: float
    chi2_dof: float
    method: str
    tau_min_fit_s: float = math.nan
    model_floor_rel: float = math.nan
    model_floor_corr_octaves: float = math.nan
    gauss_markov_level: float = math.nan
    """σ_gm (u): standard deviation of the Gauss–Markov bias; 0 when the curve does not need it."""
    gauss_markov_tc_s: float = math.nan
    """T_c (s): its correlation time; NaN when the term is 0 or not estimated."""
    gauss_markov_level_sigma: float = math.nan
    gauss_markov_tc_s_sigma: float = math.nan

    @property
    def coefficients(self) -> FloatArray:
        """(6,) [Q, N, B, K, R, σ_gm], NaN read as 0."""
        names = (*_FIELDS, "gauss_markov_level")
        return np.asarray(np.nan_to_num(np.array([getattr(self, n) for n in names]), nan=0.0), dtype=float)

    def model_adev(self, taus_s: npt.ArrayLike) -> FloatArray:
        """Allan deviation of the model at τ (s), shape of taus_s."""
        b = basis(np.atleast_1d(taus_s), self.gauss_markov_tc_s)
        return np.sqrt(b @ self.coefficients**2).reshape(np.shape(taus_s))

    def as_dict(self) -> dict[str, float | str]:
        """Plain dict (for JSON): term values, ``*_sigma``, ``chi2_dof``, ``method``."""
        out: dict[str, float | str] = {}
        for name in _FIELDS:
            out[name] = float(getattr(self, name))
            out[f"{name}_sigma"] = float(getattr(self, f"{name}_sigma"))
        out["chi2_dof"] = float(self.chi2_dof)
        out["method"] = self.method
        out["tau_min_fit_s"] = float(self.tau_min_fit_s)
        out["model_floor_rel"] = float(self.model_floor_rel)
        out["model_floor_corr_octaves"] = float(self.model_floor_corr_octaves)
        for name in ("gauss_markov_level", "gauss_markov_tc_s"):
            out[name] = float(getattr(self, name))
            out[f"{name}_sigma"] = float(getattr(self, f"{name}_sigma"))
        return out


_FIELDS = ("quantization_q", "white_n", "bias_instability_b", "rate_random_walk_k", "rate_ramp_r")
_GM_FIELDS = (
    "gauss_markov_level",
    "gauss_markov_tc_s",
    "gauss_markov_level_sigma",
    "gauss_markov_tc_s_sigma",
)


def _terms(
    values: list[float],
    sigmas: list[float],
    chi2_dof: float,
    method: str,
    tau_min_fit_s: float,
    model_floor_rel: float = math.nan,
    model_floor_corr_octaves: float = math.nan,
    gauss_markov: tuple[float, float, float, float] = (math.nan,) * 4,
) -> NoiseTerms:
    """NoiseTerms from [Q, N, B, K, R] values and sigmas, and (σ_gm, T_c, their sigmas)."""
    kwargs = dict(zip(_FIELDS, values, strict=True))
    kwargs.update({f"{name}_sigma": s for name, s in zip(_FIELDS, sigmas, strict=True)})
    kw: dict[str, float] = {
        "tau_min_fit_s": tau_min_fit_s,
        "model_floor_rel": model_floor_rel,
        "model_floor_corr_octaves": model_floor_corr_octaves,
    }
    kw.update(zip(_GM_FIELDS, gauss_markov, strict=True))
    return NoiseTerms(**kwargs, chi2_dof=chi2_dof, method=method, **kw)


def first_fit_index(adev: npt.ArrayLike) -> int:
    """Index of the first point the model can describe: 0, or the first maximum if the curve rises from τ0."""
    a = np.asarray(adev, dtype=float)
    i = 0
    while i + 1 < a.size and a[i + 1] > a[i]:
        i += 1
    return i if i + 1 < a.size else 0


def _root_with_sigma(p: float, var_p: float) -> tuple[float, float]:
    """√p and the half-width of the image of [p − σ_p, p + σ_p] under √ (σ_p as upper limit if p = 0)."""
    sp = math.sqrt(max(var_p, 0.0))
    if p <= 0.0:
        return 0.0, math.sqrt(sp)
    return math.sqrt(p), 0.5 * (math.sqrt(p + sp) - math.sqrt(max(p - sp, 0.0)))


def fit_noise_model_curve(
    taus_s: npt.ArrayLike,
    adev: npt.ArrayLike,
    edf: npt.ArrayLike,
    terms: tuple[str, ...] = TERMS,
    n_iterations: int = 6,
    tau0_s: float | None = None,
    floor_rel: float | None = None,
    floor_octaves: float | None = None,
    select: bool = True,
) -> NoiseTerms:
    """Weighted non-negative least-squares fit of the noise model to one Allan curve.

    :param taus_s: (m,) averaging times (s).
    :param adev: (m,) Allan deviation, unit u.
    :param edf: (m,) equivalent degrees of freedom of each point (≥ 1).
    :param terms: which of :data:`TERMS` to fit; the others are fixed at 0 (value NaN).
    :param n_iterations: re-weighting passes (weights and correlations from the current model).
    :param tau0_s: sampling interval of the data behind the curve (s); ``None``: the smallest τ.
    :param floor_rel: relative allowance on σ for model misfit; ``None`` (default) estimates it:
        0 unless χ² exceeds its :data:`MISFIT_LEVEL` quantile, else the value giving χ²/dof = 1.
    :param floor_octaves: correlation length of the allowance along τ (octaves,
        :func:`allowance_correlation`); ``None`` (default): by likelihood when the allowance is
        estimated (:func:`_allowance`), 0 (independent points) when floor_rel is given.
    :param select: leave out quantisation and rate ramp where the curve does not need them
        (:func:`select_terms`, module doc); a term left out reads 0 with its upper limit.
    :returns: :class:`NoiseTerms` with method ``"wls-5term"``; ``chi2_dof`` is that of the fit
        without allowance, ``model_floor_rel`` and ``model_floor_corr_octaves`` the allowance used.
    """
    t = np.asarray(taus_s, dtype=float)
    s2 = np.asarray(adev, dtype=float) ** 2
    nu = np.maximum(np.asarray(edf, dtype=float), 1.0)
    if not (t.shape == s2.shape == nu.shape and t.ndim == 1):
        raise ValueError(
            f"taus_s, adev and edf must be 1-D of one length, got {t.shape}, {s2.shape}, {nu.shape}"
        )
    unknown = [name for name in terms if name not in TERMS]
    if unknown:
        raise ValueError(f"unknown noise terms {unknown}; known: {list(TERMS)}")
    if not (np.all(np.isfinite(t)) and np.all(t > 0) and np.all(np.isfinite(s2))):
        raise ValueError("taus_s must be finite and > 0 and adev finite")
    active = sorted(TERMS.index(name) for name in terms)
    start = first_fit_index(s2)
    t, s2, nu = t[start:], s2[start:], nu[start:]
    lo_tc, hi_tc = tc_range_s(t)
    if GM in active and lo_tc > hi_tc:  # no room for a hump: the term is not estimated (NaN)
        active.remove(GM)
    if t.size < len(active) + 1:
        rising = f" (the curve rises from τ0 to τ = {t[0]:.3g} s: is the stretch static?)" if start else ""
        raise ValueError(f"{t.size} Allan points{rising} cannot determine {len(active)} noise terms")
    tau0 = float(t.min()) if tau0_s is None else float(tau0_s)
    full = fit_terms(t, s2, nu, active, tau0, n_iterations)
    bound_var = term_variances(full, max(1.0, full.chi2 / full.dof))
    # the bounded likelihood-ratio test needs the model to hold: where χ² rejects it, all terms stay
    holds = full.chi2 <= stats.chi2.ppf(MISFIT_LEVEL, full.dof)
    if not select:
        chosen = active
    elif GM in active:
        chosen = select_with_gauss_markov(t, s2, nu, active, tau0, n_iterations, full, holds)
    else:
        chosen = select_terms(t, s2, nu, active, tau0, n_iterations, full) if holds else active
    fit = full if chosen == active else fit_terms(t, s2, nu, chosen, tau0, n_iterations)
    tc = fit.tc_s  # the allowance's fits keep the Gauss–Markov T_c of the fit without it
    A = basis(t, tc)[:, chosen]
    chi2_dof = fit.chi2 / fit.dof
    floor = 0.0 if floor_rel is None else float(floor_rel)
    octaves = 0.0 if floor_octaves is None else float(floor_octaves)
    level = floor  # the allowance of the values' fit: independent between τ
    if floor_rel is None and fit.chi2 > stats.chi2.ppf(MISFIT_LEVEL, fit.dof):
        if floor_octaves is None:
            floor, octaves, level = allowance(t, s2, nu, A, chosen, tau0, n_iterations, tc)
        else:
            level = floor_for_unit_chi2(t, s2, nu, A, chosen, tau0, n_iterations, 0.0, tc)
            floor = (
                level
                if octaves == 0.0
                else floor_for_unit_chi2(t, s2, nu, A, chosen, tau0, n_iterations, octaves, tc)
            )
    var_p = term_variances(fit, max(1.0, chi2_dof))
    if floor > 0.0:
        # the values: GLS with the allowance independent between τ, which keeps the many
        # short-τ points from deciding every term. Their sigmas: the sandwich with the
        # allowance at its likelihood's correlation length (a misfit is smooth in τ), never
        # below the fit without allowance scaled by its χ²/dof (Birge ratio).
        fit = gls(t, s2, nu, A, chosen, tau0, level, n_iterations, 0.0, tc)
        fl = 2.0 * floor * fit.model
        honest = fit.stat_cov + allowance_correlation(t, octaves) * fl[:, None] * fl[None, :]
        new = term_variances(fit, max(1.0, fit.chi2 / fit.dof), honest)
        # (k,) per term, and ln T_c's variance last where this fit has the Gauss–Markov term > 0
        n_terms = len(chosen)
        head = np.maximum(new[:n_terms], var_p[:n_terms])
        tail = new[n_terms:] if var_p.size == n_terms else np.maximum(new[n_terms:], var_p[n_terms:])
        var_p = np.concatenate([head, tail])  # tail: [] where the values' fit has no T_c
    values = [math.nan] * 6
    sigmas = [math.nan] * 6
    for k, idx in enumerate(active):
        # a term the selection left out: 0 and its one-sigma upper limit from the full model
        values[idx], sigmas[idx] = _root_with_sigma(0.0, float(bound_var[k]))
    for k, idx in enumerate(chosen):
        values[idx], sigmas[idx] = _root_with_sigma(float(fit.p[k]), float(var_p[k]))
    gm = (values[GM], math.nan, sigmas[GM], math.nan)
    if fit.dtc is not None:  # the term is in and > 0: T_c and its sigma (linearised in ln T_c)
        gm = (values[GM], tc, sigmas[GM], tc * math.sqrt(max(float(var_p[-1]), 0.0)))
    corr_octaves = octaves if floor > 0.0 else math.nan
    return _terms(values[:5], sigmas[:5], chi2_dof, "wls-5term", float(t[0]), floor, corr_octaves, gm)


def fit_noise_model(result: AllanResult, terms: tuple[str, ...] = TERMS) -> tuple[NoiseTerms, ...]:
    """:func:`fit_noise_model_curve` for every channel of an :class:`AllanResult`."""
    return tuple(
        fit_noise_model_curve(
            result.taus_s, result.adev[:, c], result.edf[:, c], terms, tau0_s=1.0 / result.sample_rate_hz
        )
        for c in range(result.n_channels)
    )


def _line_reading(
    t: FloatArray,
    dev: FloatArray,
    nu: FloatArray,
    exponent: float,
    tau_read_s: float,
    mask: npt.NDArray[np.bool_],
    corr: FloatArray,
    floor_rel: float,
) -> tuple[float, float]:
    """Value at tau_read_s of the line σ ∝ τ^exponent through the masked points, and its sigma.

    Generalised mean in log space: Cov(ln σ̂_a, ln σ̂_b) = ρ_ab/(2√(ν_a ν_b)) + floor² (ρ the
    correlation of the overlapping estimates, :func:`allan_correlation`; floor the fit's
    relative model allowance, the same for every point of one line), variance 1/(1ᵀC⁻¹1),
    times the points' own χ²/dof about the line when above 1.
    """
    if not mask.any():
        return math.nan, math.nan
    logs = np.log(dev[mask]) - exponent * np.log(t[mask] / tau_read_s)
    inv_sd = np.sqrt(2.0 * nu[mask])
    cov = corr[np.ix_(mask, mask)] / inv_sd[:, None] / inv_sd[None, :] + floor_rel**2
    L = cholesky_ridged(cov)
    white = forward_solve(L, np.column_stack([np.ones(logs.size), logs]))
    one_w, logs_w = white[:, 0], white[:, 1]
    info = float(one_w @ one_w)
    mean = float(one_w @ logs_w) / info
    resid = logs_w - one_w * mean
    birge = float(resid @ resid) / (logs.size - 1) if logs.size > 1 else 1.0
    value = math.exp(mean)
    return value, value * math.sqrt(max(1.0, birge) / info)


def slope_method_curve(taus_s: npt.ArrayLike, adev: npt.ArrayLike, edf: npt.ArrayLike) -> NoiseTerms:
    """IEEE 952 Annex C slope reading of one curve: N (−1/2 line at 1 s), B (minimum/0.664), K (+1/2 at 3 s).

    Points are assigned to a line where that term carries ≥ :data:`DOMINANT_SHARE` of the variance
    of the fitted model (:func:`fit_noise_model_curve`); a term with no such point is NaN. B is
    an upper bound when the curve has no flat region (its minimum then lies where white noise
    and rate random walk cross).
    """
    t = np.asarray(taus_s, dtype=float)
    dev = np.asarray(adev, dtype=float)
    nu = np.maximum(np.asarray(edf, dtype=float), 1.0)
    # the allowance level for independent points; _line_reading makes it common to the line
    fit = fit_noise_model_curve(t, dev, nu, floor_octaves=0.0)
    parts = basis(t, fit.gauss_markov_tc_s) * fit.coefficients**2
    share = parts / np.maximum(parts.sum(axis=1, keepdims=True), np.finfo(float).tiny)
    usable = np.arange(t.size) >= first_fit_index(dev)
    corr = allan_correlation(t, fit.coefficients**2, float(t.min()), fit.gauss_markov_tc_s)
    floor = fit.model_floor_rel if math.isfinite(fit.model_floor_rel) else 0.0
    line = (t, dev, nu)
    n, n_sigma = _line_reading(*line, -0.5, 1.0, usable & (share[:, 1] >= DOMINANT_SHARE), corr, floor)
    k, k_sigma = _line_reading(*line, +0.5, 3.0, usable & (share[:, 3] >= DOMINANT_SHARE), corr, floor)
    i_min = int(np.argmin(dev))
    b = float(dev[i_min]) / BI_FACTOR
    b_sigma = b / math.sqrt(2.0 * float(nu[i_min]))
    nan = math.nan
    return _terms(
        [nan, n, b, k, nan], [nan, n_sigma, b_sigma, k_sigma, nan], nan, "ieee952-slope", fit.tau_min_fit_s
    )


def slope_method(result: AllanResult) -> tuple[NoiseTerms, ...]:
    """:func:`slope_method_curve` for every channel of an :class:`AllanResult`."""
    return tuple(
        slope_method_curve(result.taus_s, result.adev[:, c], result.edf[:, c])
        for c in range(result.n_channels)
    )
