"""Noise terms of an inertial sensor from its Allan curve (IEEE Std 952-1997 Annex C).

The standard noise model adds independent power-law processes; their Allan variances add
(IEEE 952 Table C.2, with u the unit of the rate data, e.g. m/s² for an accelerometer):

    σ²(τ) = 3Q²/τ²  +  N²/τ  +  (0.664·B)²  +  K²τ/3  +  R²τ²/2

    Q  quantisation noise                  (u·s)
    N  white noise / velocity random walk  (u·√s = u/√Hz), read at τ = 1 s on the −1/2 line
    B  bias instability                    (u),   flat floor σ = √(2 ln 2 / π)·B = 0.664·B
    K  rate random walk                    (u/√s), read at τ = 3 s on the +1/2 line
    R  rate ramp (drift)                   (u/s)

:func:`fit_noise_model` fits the five squared coefficients p = [Q², N², B², K², R²] ≥ 0 by
non-negative weighted least squares on σ̂², with each point weighted by its standard
deviation σ²(τ)·√(2/edf + (2·MODEL_FLOOR_REL)²) (a χ² variable with edf degrees of freedom,
plus a 1 % relative allowance on σ for the model itself: real sensors' filters and
non-power-law processes depart from it by that much, and without the allowance the points
at short τ, whose edf run to 10⁵, would decide every term). The weights are iterated with
the model's own σ² so that low points do not pull the fit. Points before the curve's first
maximum are left out when the curve *rises* from τ0 (a sensor low-pass filter correlates
neighbouring samples; no term of the model rises at short τ). Uncertainties come from the
weighted normal matrix of the active terms, scaled up by √(χ²/dof) when the fit is worse
than the intervals say. Allan points at neighbouring τ are positively correlated, which
this treats as independent; see the tests for the coverage that results.

:func:`slope_method` is the graphical reading of Annex C: N from the points on the −1/2
line (read at τ = 1 s), K from the points on the +1/2 line (read at τ = 3 s), B from the
curve's minimum / 0.664.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import nnls

from bench.estimation.allan import AllanResult

FloatArray = npt.NDArray[np.float64]

BI_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
"""0.6643: Allan deviation of the bias-instability floor per unit B (IEEE 952 Table C.2)."""

TERMS = ("quantization", "white", "bias_instability", "rate_random_walk", "rate_ramp")
"""Term names, in the order of :func:`basis`."""

MODEL_FLOOR_REL = 0.01
"""Relative allowance on the Allan deviation for the noise model's own inexactness."""

OCTAVE_CORRELATION = {2: 0.5, 1: 0.5, 0: 0.53, -1: 0.68, -2: 0.88}
"""Correlation of Allan estimates one octave apart, by power-law α (Monte-Carlo, see module doc)."""

DOMINANT_SHARE = 0.8
"""Slope method: a point belongs to a term's line where that term is ≥ 80 % of the model variance."""


def basis(taus_s: npt.ArrayLike) -> FloatArray:
    """(m, 5) Allan variance per unit squared coefficient: 3/τ², 1/τ, 0.664², τ/3, τ²/2."""
    t = np.asarray(taus_s, dtype=float)
    return np.stack([3.0 / t**2, 1.0 / t, np.full_like(t, BI_FACTOR**2), t / 3.0, t**2 / 2.0], axis=1)


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

    @property
    def coefficients(self) -> FloatArray:
        """(5,) [Q, N, B, K, R], NaN read as 0."""
        return np.nan_to_num(np.array([getattr(self, name) for name in _FIELDS]), nan=0.0)

    def model_adev(self, taus_s: npt.ArrayLike) -> FloatArray:
        """Allan deviation of the model at τ (s), shape of taus_s."""
        return np.sqrt(basis(np.atleast_1d(taus_s)) @ self.coefficients**2).reshape(np.shape(taus_s))

    def as_dict(self) -> dict[str, float | str]:
        """Plain dict (for JSON): term values, ``*_sigma``, ``chi2_dof``, ``method``."""
        out: dict[str, float | str] = {}
        for name in _FIELDS:
            out[name] = float(getattr(self, name))
            out[f"{name}_sigma"] = float(getattr(self, f"{name}_sigma"))
        out["chi2_dof"] = float(self.chi2_dof)
        out["method"] = self.method
        out["tau_min_fit_s"] = float(self.tau_min_fit_s)
        return out


_FIELDS = ("quantization_q", "white_n", "bias_instability_b", "rate_random_walk_k", "rate_ramp_r")


def _terms(
    values: list[float], sigmas: list[float], chi2_dof: float, method: str, tau_min_fit_s: float
) -> NoiseTerms:
    """NoiseTerms from [Q, N, B, K, R] values and sigmas."""
    kwargs = dict(zip(_FIELDS, values, strict=True))
    kwargs.update({f"{name}_sigma": s for name, s in zip(_FIELDS, sigmas, strict=True)})
    return NoiseTerms(**kwargs, chi2_dof=chi2_dof, method=method, tau_min_fit_s=tau_min_fit_s)


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


def _alpha_from_slope(t: FloatArray, s2: FloatArray) -> npt.NDArray[np.int64]:
    """(m,) α from the local log-log slope μ of σ²(τ): α = −μ − 1, rounded into [−2, 0]."""
    if t.size < 2:
        return np.zeros(t.size, dtype=np.int64)
    mu = np.gradient(np.log(s2), np.log(t))
    return np.clip(np.rint(-mu - 1.0), -2, 0).astype(np.int64)


def _ar1_cholesky(t: FloatArray, alpha: npt.ArrayLike) -> FloatArray:
    """Lower Cholesky factor of the AR(1) correlation of Allan points along τ."""
    a = np.asarray(alpha)
    rho_oct = np.array([OCTAVE_CORRELATION[int(np.clip(x, -2, 2))] for x in a])
    rho_pair = np.sqrt(rho_oct[:-1] * rho_oct[1:]) ** np.log2(t[1:] / t[:-1])
    log_cum = np.concatenate([[0.0], np.cumsum(np.log(np.maximum(rho_pair, 1e-300)))])
    corr = np.exp(-np.abs(log_cum[:, None] - log_cum[None, :]))
    return np.linalg.cholesky(corr + 1e-12 * np.eye(t.size))


def fit_noise_model_curve(
    taus_s: npt.ArrayLike,
    adev: npt.ArrayLike,
    edf: npt.ArrayLike,
    terms: tuple[str, ...] = TERMS,
    alpha: npt.ArrayLike | None = None,
    n_iterations: int = 6,
) -> NoiseTerms:
    """Weighted non-negative least-squares fit of the noise model to one Allan curve.

    :param taus_s: (m,) averaging times (s).
    :param adev: (m,) Allan deviation, unit u.
    :param edf: (m,) equivalent degrees of freedom of each point (≥ 1).
    :param terms: which of :data:`TERMS` to fit; the others are fixed at 0 (value NaN).
    :param alpha: (m,) power-law α of each point (:attr:`AllanResult.alpha`) for the correlation
        model; ``None`` takes it from the curve's local slope.
    :returns: :class:`NoiseTerms` with method ``"wls-5term"``.
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
    active = [TERMS.index(name) for name in terms]
    start = first_fit_index(s2)
    al = _alpha_from_slope(t, s2) if alpha is None else np.asarray(alpha, dtype=np.int64)
    t, s2, nu, al = t[start:], s2[start:], nu[start:], al[start:]
    if t.size < len(active) + 1:
        rising = f" (the curve rises from τ0 to τ = {t[0]:.3g} s: is the stretch static?)" if start else ""
        raise ValueError(f"{t.size} Allan points{rising} cannot determine {len(active)} noise terms")
    A = basis(t)[:, active]
    L = _ar1_cholesky(t, al)
    model = np.maximum(s2, np.max(s2) * 1e-300)
    p = np.zeros(len(active))
    rel_sd = np.sqrt(2.0 / nu + (2.0 * MODEL_FLOOR_REL) ** 2)

    def whiten(v: FloatArray, sd: FloatArray) -> FloatArray:
        return np.asarray(np.linalg.solve(L, v / (sd[:, None] if v.ndim == 2 else sd)), dtype=float)

    for _ in range(n_iterations):
        sd = model * rel_sd
        As = whiten(A, sd)
        scale = np.linalg.norm(As, axis=0)
        p_scaled, _ = nnls(As / scale, whiten(s2, sd))
        p = p_scaled / scale
        model = np.maximum(A @ p, np.max(s2) * 1e-12)
    sd = model * rel_sd
    As = whiten(A, sd)
    chi2 = float(np.sum(whiten(s2 - A @ p, sd) ** 2))
    positive = p > 0
    dof = max(t.size - int(positive.sum()), 1)
    chi2_dof = chi2 / dof
    inflate = max(1.0, chi2_dof)
    var_p = np.zeros(len(active))
    if positive.any():
        J = As[:, positive]
        var_p[positive] = np.diag(np.linalg.pinv(J.T @ J)) * inflate
    for j in np.flatnonzero(~positive):
        cols = np.append(np.flatnonzero(positive), j)
        J = As[:, cols]
        var_p[j] = np.linalg.pinv(J.T @ J)[-1, -1] * inflate
    values = [math.nan] * 5
    sigmas = [math.nan] * 5
    for k, idx in enumerate(active):
        values[idx], sigmas[idx] = _root_with_sigma(float(p[k]), float(var_p[k]))
    return _terms(values, sigmas, chi2_dof, "wls-5term", float(t[0]))


def fit_noise_model(result: AllanResult, terms: tuple[str, ...] = TERMS) -> tuple[NoiseTerms, ...]:
    """:func:`fit_noise_model_curve` for every channel of an :class:`AllanResult`."""
    return tuple(
        fit_noise_model_curve(result.taus_s, result.adev[:, c], result.edf[:, c], terms, result.alpha[:, c])
        for c in range(result.n_channels)
    )


def _line_reading(
    t: FloatArray,
    dev: FloatArray,
    nu: FloatArray,
    exponent: float,
    tau_read_s: float,
    mask: npt.NDArray[np.bool_],
) -> tuple[float, float]:
    """Value at tau_read_s of the line σ ∝ τ^exponent through the masked points, and its sigma.

    Weighted mean in log space, var(ln σ̂) ≈ 1/(2·edf) per point.
    """
    if not mask.any():
        return math.nan, math.nan
    logs = np.log(dev[mask]) - exponent * np.log(t[mask] / tau_read_s)
    w = 2.0 * nu[mask]
    mean = float(np.sum(w * logs) / np.sum(w))
    value = math.exp(mean)
    return value, value / math.sqrt(float(np.sum(w)))


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
    fit = fit_noise_model_curve(t, dev, nu)
    parts = basis(t) * fit.coefficients**2
    share = parts / np.maximum(parts.sum(axis=1, keepdims=True), np.finfo(float).tiny)
    usable = np.arange(t.size) >= first_fit_index(dev)
    n, n_sigma = _line_reading(t, dev, nu, -0.5, 1.0, usable & (share[:, 1] >= DOMINANT_SHARE))
    k, k_sigma = _line_reading(t, dev, nu, +0.5, 3.0, usable & (share[:, 3] >= DOMINANT_SHARE))
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
