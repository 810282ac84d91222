"""The covariance a static window fit reaches on a design, and the white-noise bound of any
motion.

Design: m static windows, window w with specific force f_w (m/s², sensor frame) and the
model of ``bench.estimation.static_fit``, y_w = b + K f_w + e_w, parameters in its order
θ = [b_x, b_y, b_z, K_xx, K_xy, …, K_zz] (K ≈ I, channels in m/s²). A base tilt δ = (δ_x, δ_y)
(rad, rotations of the table's base about its x and y axes) may be carried as two nuisance
parameters: gravity in the base frame becomes g·(δ_y, −δ_x, 1), so the window's force moves
by ∂f_w/∂δ = R_wᵀ·g·[[0, 1], [−1, 0], [0, 0]] (R_w the table's rotation, f_w = R_wᵀ·[0, 0, g]);
with the outer axis turning between poses this is separable from K.

The noise e is independent between channels and, per channel, has the covariance C (m, m) of
the window means (:func:`bench.planning.noise.window_mean_covariance`: white + wander + random
walk). The generalised-least-squares fit with that covariance has

    Cov(θ) = (Σ_i H_iᵀ C⁻¹ H_i)⁻¹,   H_i (m, p) the rows of channel i,

which is also the Cramér–Rao bound of the Gaussian model (Kay, *Fundamentals of Statistical
Signal Processing I*, §3.9 / §4.5): the "information matrix with the coloured noise in it".

Bound of any motion: with white noise of density N only, a recording of T s whose specific
force f(t) (|f| = g) is spread evenly over the sphere (mean 0, second moment g²/3·I) has per
channel information (T/N²)·diag(1, g²/3, g²/3, g²/3) on [b_i, K_i·] — the largest trace-
uniform information any motion can give, since |f| = g fixes the trace of E[f fᵀ]. Hence

    σ(b) ≥ N/√T,   σ(K_ij) ≥ √3·N/(g·√T)

(the same holds for an isotropic set of static poses; Panahandeh et al., IPIN 2010).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.linalg import solve_triangular

FloatArray = npt.NDArray[np.float64]

N_CORE = 12
"""Bias (3) and K (9): the parameters a target can name."""


@dataclass(frozen=True)
class PredictedUncertainty:
    """Standard uncertainties (k = 1) a design is predicted to reach.

    :param cov: (p, p) covariance of [b (m/s²), K (1), tilt (rad)…] in the fit's order.
    :param bias_m_s2: (3,) σ of each bias.
    :param k_elements: (3, 3) σ of each K element (dimensionless).
    :param tilt_rad: (2,) σ of the tilt, or empty when it is not a parameter.
    :param nuisance: σ of the every-sample fit's nuisance parameters in the order of
        ``bench.planning.trajectory.NUISANCE_NAMES`` (lever arm m, tilt rad), or empty.
    """

    cov: FloatArray
    bias_m_s2: FloatArray
    k_elements: FloatArray
    tilt_rad: FloatArray
    nuisance: FloatArray = field(default_factory=lambda: np.zeros(0))

    @property
    def scale(self) -> float:
        """Largest σ of a scale factor (diagonal of K)."""
        return float(np.max(np.diag(self.k_elements)))

    @property
    def misalignment(self) -> float:
        """Largest σ of an off-diagonal element of K (rad)."""
        off = self.k_elements[~np.eye(3, dtype=bool)]
        return float(np.max(off))

    @property
    def bias(self) -> float:
        """Largest σ of a bias (m/s²)."""
        return float(np.max(self.bias_m_s2))

    @property
    def k_rms(self) -> float:
        """RMS over the nine K elements of their σ (the 'K error' of docs/planning.md)."""
        return float(np.sqrt(np.mean(self.k_elements**2)))


def design_matrix(f_m_s2: FloatArray, tilt_response: FloatArray | None = None) -> FloatArray:
    """(3, m, p) rows H_i of each channel: [e_i, e_i ⊗ f_wᵀ, (∂f_w/∂δ)_i].

    :param f_m_s2: (m, 3) specific force per window (m/s²).
    :param tilt_response: (m, 3, 2) ∂f_w/∂δ (m/s² per rad), or ``None`` (no tilt parameter).
    """
    f = np.asarray(f_m_s2, dtype=float)
    m = f.shape[0]
    p = N_CORE + (0 if tilt_response is None else 2)
    H = np.zeros((3, m, p))
    for i in range(3):
        H[i, :, i] = 1.0
        H[i, :, 3 + 3 * i : 6 + 3 * i] = f
        if tilt_response is not None:
            H[i, :, N_CORE:] = tilt_response[:, i, :]
    return H


def tilt_response(R_sensor_from_base: FloatArray, g_m_s2: float) -> FloatArray:
    """(m, 3, 2) ∂f_w/∂δ for rotations R_w (m, 3, 3) taking base vectors to the sensor frame."""
    D = g_m_s2 * np.array([[0.0, 1.0], [-1.0, 0.0], [0.0, 0.0]])
    response: FloatArray = np.einsum("wij,jk->wik", np.asarray(R_sensor_from_base, dtype=float), D)
    return response


def predicted_uncertainty(
    f_m_s2: FloatArray, window_cov: FloatArray, tilt_resp: FloatArray | None = None
) -> PredictedUncertainty:
    """Cov(θ) = (Σ_i H_iᵀ C⁻¹ H_i)⁻¹ of the GLS window fit (module docstring).

    :param f_m_s2: (m, 3) specific force per window (m/s²).
    :param window_cov: (m, m) covariance of one channel's window means ((m/s²)²).
    :param tilt_resp: (m, 3, 2) tilt response, or ``None``.
    :raises ValueError: the design cannot identify the parameters (singular information).
    """
    H = design_matrix(f_m_s2, tilt_resp)
    C = np.asarray(window_cov, dtype=float)
    L = np.linalg.cholesky(C)
    m = C.shape[0]
    W = (
        solve_triangular(L, H.transpose(1, 0, 2).reshape(m, -1), lower=True)
        .reshape(m, 3, -1)
        .transpose(1, 0, 2)
    )
    info = np.einsum("imp,imq->pq", W, W)
    cond = np.linalg.cond(info)
    if not np.isfinite(cond) or cond > 1e15:
        raise ValueError(f"the design does not identify all parameters (information condition {cond:.2g})")
    cov = np.linalg.inv(info)
    cov = 0.5 * (cov + cov.T)
    sd = np.sqrt(np.diag(cov))
    return PredictedUncertainty(cov, sd[:3].copy(), sd[3:12].reshape(3, 3).copy(), sd[12:].copy())


def white_bound_k(white_m_s2_rt_hz: float, duration_s: float, g_m_s2: float) -> float:
    """σ(K_ij) ≥ √3·N/(g·√T): the best any motion of ``duration_s`` can do with white noise."""
    return math.sqrt(3.0) * white_m_s2_rt_hz / (g_m_s2 * math.sqrt(duration_s))


def white_bound_bias(white_m_s2_rt_hz: float, duration_s: float) -> float:
    """σ(b_i) ≥ N/√T (m/s²)."""
    return white_m_s2_rt_hz / math.sqrt(duration_s)


def wander_bound_bias(wander_m_s2: float, wander_tau_s: float, span_s: float) -> float:
    """σ(b_i) ≥ B·√(2T_c / (T + 2T_c)) (m/s²) for any design within ``span_s`` = T seconds: the
    best linear unbiased estimate of a constant observed for T s in a Gauss-Markov wander of
    standard deviation B and correlation time T_c (the continuous limit of the AR(1) mean,
    σ²(1+ρ)/(n(1−ρ)+2ρ) with ρ = e^{−Δ/T_c}, which is never below it since x ≥ 2·tanh(x/2)).
    Window means, samples and other parameters beside the bias are linear functions of that
    record, and white noise or a random walk on top only add variance, so no fit does better:
    the bias is wander-limited whatever the motion. 0 without a wander."""
    if wander_m_s2 <= 0:
        return 0.0
    return wander_m_s2 * math.sqrt(2.0 * wander_tau_s / (span_s + 2.0 * wander_tau_s))


def time_for_k(white_m_s2_rt_hz: float, sigma_k: float, g_m_s2: float) -> float:
    """The shortest table time (s) at which the white-noise bound reaches σ(K_ij) = ``sigma_k``."""
    return 3.0 * (white_m_s2_rt_hz / (g_m_s2 * sigma_k)) ** 2
