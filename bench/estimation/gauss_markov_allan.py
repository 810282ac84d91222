"""Allan variance and spectrum of a first-order Gauss–Markov bias.

A stationary first-order Gauss–Markov (Ornstein–Uhlenbeck) process of standard deviation
σ_gm (unit u) and correlation time T_c (s), dx/dt = −x/T_c + q·w, q² = 2σ_gm²/T_c, has the
Allan variance (IEEE Std 952-1997 Annex C; Xing & Gebre-Egziabher, "Modeling and bounding
low cost inertial sensor errors", IEEE/ION PLANS 2008, eqn 14)

    σ²(τ) = (q² T_c² / τ) · [1 − (T_c / 2τ)(3 − 4 e^(−τ/T_c) + e^(−2τ/T_c))]
          = σ_gm² · g(τ; T_c),   g = (2 T_c / τ) · [ … ]

It rises as q²τ/3 (a rate random walk of K = q) for τ ≪ T_c, peaks at τ = 1.89 T_c with
σ(τ) = 0.617 σ_gm, and falls as 2σ_gm² T_c / τ (a white noise of N² = 2σ_gm² T_c) for τ ≫ T_c:
the hump a power-law model (N, flat B, K) cannot follow. Its one-sided spectrum is the
Lorentzian S_y(f) = 4 σ_gm² T_c / (1 + (2π f T_c)²).

Shapes: ``taus_s`` (m,) in s; results (m,), per unit σ_gm² (u²).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

_SERIES_BELOW = 1e-3
"""τ/T_c below which the bracket is evaluated by its series (cancellation in 3 − 4e^−x + e^−2x)."""


def gm_basis(taus_s: npt.ArrayLike, tc_s: float) -> FloatArray:
    """(m,) g(τ; T_c): Allan variance of a Gauss–Markov process per unit σ_gm² (module doc)."""
    t = np.asarray(taus_s, dtype=float)
    if not (math.isfinite(tc_s) and tc_s > 0.0):
        raise ValueError(f"Gauss–Markov correlation time must be finite and > 0 s, got {tc_s!r}")
    x = t / tc_s
    # 1 − (3 − 4e^−x + e^−2x)/(2x); series x²/3 − x³/4 + 7x⁴/60 for small x
    bracket = np.where(
        x < _SERIES_BELOW,
        x**2 / 3.0 - x**3 / 4.0 + 7.0 * x**4 / 60.0,
        1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * np.maximum(x, _SERIES_BELOW)),
    )
    return np.asarray(2.0 / x * bracket, dtype=float)


def gm_basis_dlog_tc(taus_s: npt.ArrayLike, tc_s: float) -> FloatArray:
    """(m,) ∂g/∂ln T_c at (τ, T_c), by a central difference of step 10⁻⁴ in ln T_c."""
    h = 1e-4
    return (gm_basis(taus_s, tc_s * math.exp(h)) - gm_basis(taus_s, tc_s * math.exp(-h))) / (2.0 * h)


def gm_spectrum(f_hz: npt.ArrayLike, var: float, tc_s: float) -> FloatArray:
    """(n,) one-sided spectrum 4·var·T_c / (1 + (2π f T_c)²) (u²/Hz) of a Gauss–Markov process
    of variance var (u²) at frequencies f_hz (n,)."""
    f = np.asarray(f_hz, dtype=float)
    return np.asarray(4.0 * var * tc_s / (1.0 + (2.0 * math.pi * f * tc_s) ** 2), dtype=float)
