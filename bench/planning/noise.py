"""The unit's noise as the planner sees it, and the covariance of window means it causes.

Per channel, independent between channels and identical on the three (IEEE Std 952 terms,
the same processes as ``drivers.sim.noise``):

- white noise of density N (m/s²/√Hz, Allan σ_A(τ) = N/√τ): the mean of a window of T s has
  variance N²/T;
- a first-order Gauss-Markov wander of standard deviation B (m/s²) and correlation time T_c
  (s), covariance B²·exp(−|t − s|/T_c);
- a bias random walk of coefficient K (m/s² per √s), covariance K²·min(t, s) from the run's
  start (t = 0).

The covariance of the means of windows [a₁, b₁] and [a₂, b₂] (lengths T₁, T₂) is the double
integral of the kernel over the two windows divided by T₁T₂. Closed forms (derived from the
kernels above):

    white:   N²/T                                   (same window; 0 otherwise)
    GM:      B²·2T_c(T − T_c(1 − e^{−T/T_c}))/T²     (same window)
             B²·T_c²(e^{−(a₂−b₁)/T_c} − e^{−(a₂−a₁)/T_c} − e^{−(b₂−b₁)/T_c} + e^{−(b₂−a₁)/T_c})/(T₁T₂)
                                                     (a₂ ≥ b₁)
    RW:      K²(a + T/3)                             (same window)
             K²(a₁ + b₁)/2                           (a₂ ≥ b₁)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

G0_M_S2 = 9.80665
"""Standard gravity: µg figures are converted with it (m/s² per g)."""


@dataclass(frozen=True)
class UnitNoise:
    """Noise of one channel (the same on all three), SI units.

    :param white_m_s2_rt_hz: white-noise density N (m/s²/√Hz).
    :param wander_m_s2: Gauss-Markov standard deviation B (m/s²); 0 = none.
    :param wander_tau_s: its correlation time T_c (s).
    :param random_walk_m_s2_rt_s: bias random-walk coefficient K (m/s² per √s); 0 = none.
    """

    white_m_s2_rt_hz: float
    wander_m_s2: float = 0.0
    wander_tau_s: float = 100.0
    random_walk_m_s2_rt_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("white_m_s2_rt_hz", "wander_m_s2", "wander_tau_s", "random_walk_m_s2_rt_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"noise {name}: expected a finite number >= 0, got {v!r}")
        if self.white_m_s2_rt_hz <= 0:
            raise ValueError(f"noise white_m_s2_rt_hz must be > 0, got {self.white_m_s2_rt_hz!r}")
        if self.wander_m_s2 > 0 and self.wander_tau_s <= 0:
            raise ValueError(f"noise wander_tau_s must be > 0 with a wander, got {self.wander_tau_s!r}")

    @classmethod
    def from_ug(
        cls,
        white_ug_rt_hz: float,
        wander_ug: float = 0.0,
        wander_tau_s: float = 100.0,
        rw_ug_rt_s: float = 0.0,
    ) -> UnitNoise:
        """The same noise with µg figures (µg/√Hz, µg, s, µg/√s)."""
        k = 1e-6 * G0_M_S2
        return cls(white_ug_rt_hz * k, wander_ug * k, wander_tau_s, rw_ug_rt_s * k)

    def describe(self) -> str:
        """One line in µg."""
        k = 1e6 / G0_M_S2
        parts = [f"white {self.white_m_s2_rt_hz * k:.3g} ug/rtHz"]
        if self.wander_m_s2 > 0:
            parts.append(f"wander {self.wander_m_s2 * k:.3g} ug (correlation {self.wander_tau_s:.3g} s)")
        if self.random_walk_m_s2_rt_s > 0:
            parts.append(f"random walk {self.random_walk_m_s2_rt_s * k:.3g} ug/rts")
        return ", ".join(parts)


GM_ALLAN_PEAK = 0.6179
"""Largest Allan deviation of a first-order Gauss-Markov process of standard deviation q, over q
(reached at τ ≈ 1.89·T_c; IEEE Std 952 Annex C, C.7, exponentially correlated noise)."""
GM_PEAK_TAU = 1.89
"""τ of that peak over the correlation time T_c."""


def from_allan_terms(
    white_n: float, bias_instability_b: float, rate_random_walk_k: float, tau_floor_s: float
) -> UnitNoise:
    """The planner's noise from Allan terms of one channel (IEEE 952 model, SI units).

    N and the random walk K carry over. The bias-instability floor σ_A = 0.664·B is represented by
    a Gauss-Markov wander whose Allan peak matches it: q = 0.664·B / :data:`GM_ALLAN_PEAK`,
    T_c = τ_floor / :data:`GM_PEAK_TAU` (τ_floor: where the fitted curve is lowest). A flicker floor
    is flat over decades where the Gauss-Markov peak is about one decade wide, so the plan is
    right for dwells and passes near τ_floor and conservative elsewhere.

    :param tau_floor_s: τ of the Allan minimum (s), > 0.
    """
    if not (math.isfinite(tau_floor_s) and tau_floor_s > 0):
        raise ValueError(f"tau_floor_s must be > 0, got {tau_floor_s!r}")
    q = 0.664 * bias_instability_b / GM_ALLAN_PEAK
    return UnitNoise(white_n, q, tau_floor_s / GM_PEAK_TAU if q > 0 else 100.0, rate_random_walk_k)


def window_mean_covariance(noise: UnitNoise, start_s: FloatArray, duration_s: FloatArray) -> FloatArray:
    """(m, m) covariance of the m window means of one channel (m/s²)², see the module docstring.

    :param start_s: (m,) window starts on the run's clock (s), t = 0 the run's start.
    :param duration_s: (m,) window lengths (s), > 0; windows must not overlap.
    :raises ValueError: shapes differ, a length is not positive, or windows overlap.
    """
    a = np.asarray(start_s, dtype=float).reshape(-1)
    T = np.asarray(duration_s, dtype=float).reshape(-1)
    if a.shape != T.shape or not np.all(np.isfinite(a)) or not np.all(np.isfinite(T)) or np.any(T <= 0):
        raise ValueError("window starts and durations: expected finite (m,) arrays with durations > 0")
    order = np.argsort(a)
    b = a + T
    if np.any(a[order][1:] < b[order][:-1] - 1e-9):
        raise ValueError("windows overlap: the planner's covariance needs disjoint windows")
    C = np.diag(noise.white_m_s2_rt_hz**2 / T)
    # i earlier, j later: lo = earlier window, hi = later window
    early = a[:, None] <= a[None, :]
    a1 = np.where(early, a[:, None], a[None, :])
    b1 = np.where(early, b[:, None], b[None, :])
    a2 = np.where(early, a[None, :], a[:, None])
    b2 = np.where(early, b[None, :], b[:, None])
    TT = T[:, None] * T[None, :]
    same = np.eye(a.size, dtype=bool)
    if noise.wander_m_s2 > 0:
        tc = noise.wander_tau_s
        # a correlation time far below the gaps overflows x / T_c to +inf, and exp(-inf) = 0 is
        # the exact limit (no correlation across the gap): the overflow is not an error here
        with np.errstate(over="ignore"):
            cross = tc**2 * (
                np.exp(-np.clip(a2 - b1, 0, None) / tc)
                - np.exp(-(a2 - a1) / tc)
                - np.exp(-(b2 - b1) / tc)
                + np.exp(-(b2 - a1) / tc)
            )
            own = 2 * tc * (T - tc * (-np.expm1(-T / tc)))
        C += noise.wander_m_s2**2 * np.where(same, np.diag(own), cross) / TT
    if noise.random_walk_m_s2_rt_s > 0:
        cross = (a1 + b1) / 2
        own = a + T / 3
        C += noise.random_walk_m_s2_rt_s**2 * np.where(same, np.diag(own), cross)
    return C
