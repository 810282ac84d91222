"""Covariance of overlapping Allan variance estimates across τ, and of a model's misfit.

:func:`allan_correlation`: the correlation of σ̂²(τ_a) and σ̂²(τ_b) for a Gaussian power-law
process of given spectrum (the sampling part). :func:`allowance_correlation`: the
correlation along τ of a model allowance (the part a power-law model leaves out). Used by
``bench.estimation.noise_terms`` for the GLS of the noise terms and their sigmas.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from bench.estimation.gauss_markov_allan import gm_spectrum

FloatArray = npt.NDArray[np.float64]


def spectrum_coefficients(p: npt.ArrayLike) -> FloatArray:
    """(4,) one-sided power-law coefficients [h₂, h₀, h₋₁, h₋₂] of S_y(f) = Σ h_α f^α from p.

    p = [Q², N², B², K², R²] (R, a deterministic ramp, has no spectrum). SP1065 Table 2 with
    IEEE 952 Table C.2: h₀ = 2N², h₋₁ = B²/π, h₋₂ = K²/(2π²); white phase noise h₂ = 4π²Q²·τ0·2
    (its Allan variance 3 f_h h₂/(4π²τ²) = 3Q²/τ² with f_h = 1/(2τ0)).
    """
    q2, n2, b2, k2, _ = np.asarray(p, dtype=float)[:5]
    return np.asarray(
        np.array([0.0, 2.0 * n2, b2 / math.pi, k2 / (2.0 * math.pi**2)])
        + np.array([8.0 * math.pi**2 * q2, 0.0, 0.0, 0.0]),
        dtype=float,
    )


def allan_correlation(
    taus_s: FloatArray, p: npt.ArrayLike, tau0_s: float, tc_s: float = math.nan
) -> FloatArray:
    """(m, m) correlation of overlapping Allan variance estimates at taus_s under the model p.

    p: [Q², N², B², K², R²] (5,) or with a Gauss–Markov variance σ_gm² (6,), whose
    correlation time tc_s (s) then adds its Lorentzian (:func:`gm_spectrum`) to S_y.

    For a Gaussian process the overlapping estimate is a quadratic form of the second
    differences d_a; for a record long against the τ involved,
    Cov(σ̂²_a, σ̂²_b) ∝ Σ_h Cov(d_a(i), d_b(i+h))² = ∫ S_y(f)² W_a(f) W_b(f) df (Parseval), so

        ρ_ab = ∫ S² W_a W_b df / √(∫ S² W_a² df · ∫ S² W_b² df),

    W_τ(f) = 2 sin⁴(πfτ) / (m² sin²(πfτ0)) the Allan transfer function of m = τ/τ0 sampled
    points (SP1065 §5.2; Greenhall, "Estimating the modified Allan variance", 1995, for the
    quadratic-form covariance), S_y from :func:`spectrum_coefficients`, f up to 1/(2τ0).
    sin⁴ is replaced by its mean 3/8 beyond ten periods, where the other factors are smooth.
    """
    t = np.asarray(taus_s, dtype=float)
    h = spectrum_coefficients(p)
    f, df, W = _allan_transfer(t.tobytes(), float(tau0_s))
    S = h[0] * f**2 + h[1] + h[2] / f + h[3] / f**2
    pv = np.asarray(p, dtype=float)
    if pv.size > 5 and pv[5] > 0.0 and math.isfinite(tc_s):
        S = S + gm_spectrum(f, float(pv[5]), tc_s)
    wts = df * S**2
    G = np.einsum("af,bf->ab", W * wts, W)  # einsum: no BLAS threads for a small product
    d = np.sqrt(np.maximum(np.diag(G), np.finfo(float).tiny))
    R = np.asarray(G / d[:, None] / d[None, :], dtype=float)
    np.fill_diagonal(R, 1.0)  # also for a τ where the model has no variance at all
    return R


@lru_cache(maxsize=32)
def _allan_transfer(taus_bytes: bytes, tau0_s: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(f (n,), df (n,), W (m, n)): the frequency grid of :func:`allan_correlation` and W_τ(f) on it.

    Cached by the τ grid (its bytes) and τ0: a fit evaluates the correlation for many models
    on one grid.
    """
    t = np.frombuffer(taus_bytes, dtype=float)
    f_nyq = 0.5 / tau0_s
    f = np.geomspace(f_nyq * 1e-4 * tau0_s / t.max(), f_nyq, 2048)
    x = np.pi * f[None, :] * t[:, None]
    s4 = np.where(x < 20.0 * np.pi, np.sin(x) ** 4, 0.375)
    m = t[:, None] / tau0_s
    W = np.asarray(2.0 * s4 / (m**2 * np.sin(np.pi * f * tau0_s) ** 2), dtype=float)
    for a in (f, W):
        a.flags.writeable = False
    df = np.gradient(f)
    df.flags.writeable = False
    return f, df, W


def allowance_correlation(taus_s: npt.ArrayLike, length_octaves: float) -> FloatArray:
    """(m, m) correlation of the model allowance between τ: exp(−|log₂(τ_a/τ_b)| / length).

    A model that misses part of the spectrum (a sensor filter, a Gauss–Markov bias, flicker
    where the model has none) errs by a smooth function of τ: neighbouring points share the
    error. Modelled as a Gaussian process along log τ with exponential (Ornstein–Uhlenbeck)
    covariance, the model-discrepancy term of Kennedy & O'Hagan, "Bayesian calibration of
    computer models", JRSS B 63 (2001); length 0 is the identity (independent points).
    """
    lt = np.log2(np.asarray(taus_s, dtype=float))
    if length_octaves <= 0.0:
        return np.eye(lt.size)
    return np.asarray(np.exp(-np.abs(lt[:, None] - lt[None, :]) / length_octaves), dtype=float)


def cholesky_ridged(cov: FloatArray) -> FloatArray:
    """Lower Cholesky factor of cov, with a relative ridge 10⁻¹²…10⁻⁴ (closely spaced τ: ρ → 1)."""
    ridge = 1e-12
    while True:
        try:
            return np.asarray(np.linalg.cholesky(cov + ridge * np.diag(np.diag(cov))), dtype=float)
        except np.linalg.LinAlgError:
            if ridge >= 1e-4:
                raise
            ridge *= 100.0


def forward_solve(L: FloatArray, b: FloatArray) -> FloatArray:
    """L⁻¹·b for lower-triangular L (m, m) and b (m, k), row by row (small m; no BLAS threads)."""
    x = np.empty_like(b)
    for i in range(L.shape[0]):
        x[i] = (b[i] - L[i, :i] @ x[:i]) / L[i, i]
    return x
