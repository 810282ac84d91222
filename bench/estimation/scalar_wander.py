"""A wander shared by the windows in the orientation-free (|f| = g) calibration, in O(m).

The scalar fit (``scalar_fit``) compares each window's corrected magnitude with g:
r_w = |L⁻¹(ȳ_w − b)| − g, with variance b_w = σ_w² + ν² (the window's own noise and the
independent excess between windows). A slow bias wander s(t) (3,), input-referred, isotropic
(variance ω² per axis, first-order Gauss-Markov with correlation time T_c) moves r_w by
n_wᵀ s(t_w) to first order (n_w the unit direction of the corrected reading), so

    Cov(r) = diag(b_w) + ω² (N ∘ P),   N_ww' = n_wᵀ n_w',   P_ww' = exp(−|t_w − t_w'| / T_c).

As in ``window_covariance`` the wander is a Markov state (3 per window) observed through
the 1 × 3 loading n_wᵀ, and C⁻¹, ln|C| come from a banded Cholesky factor of
M = S⁻¹ + Σ_w n_w n_wᵀ / b_w (Woodbury, determinant lemma). ω² and T_c are estimated by
REML on the linearised fit (design J, the Jacobian of r at the solution; REML does not
depend on where along J the residuals sit) and used only when they beat ω² = 0 by
``static_wander.WANDER_GATE``; then Cov(θ) = (Jᵀ C⁻¹ J)⁻¹ with ω² inflated by ν/(ν − 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded
from scipy.optimize import minimize, minimize_scalar

from bench.estimation.scalar_fit import _TRIL, FloatArray, ScalarFit, _residual_and_jacobian
from bench.estimation.static_wander import WANDER_GATE, correlation_time_grid
from bench.estimation.window_noise import t_factor


@dataclass(frozen=True)
class ScalarWander:
    """The correlated wander of an orientation-free fit.

    :param cov: (9, 9) covariance of the parameters with the wander (``scalar_fit`` order).
    :param omega_m_s2: ω, the wander's level per axis (m/s²), inflated.
    :param corr_time_s: T_c (s).
    :param lr: 2 Δℓ_REML over no correlated wander.
    """

    cov: FloatArray
    omega_m_s2: float
    corr_time_s: float
    lr: float


def _quadratic(
    Y: FloatArray, b: FloatArray, n: FloatArray, t_s: FloatArray, omega2: float, tc: float
) -> tuple[FloatArray, float]:
    """Yᵀ C⁻¹ Y (q, q) and ln|C| for C of the module docstring; rows already in time order."""
    m = b.shape[0]
    W = Y / b[:, None]
    Q = np.einsum("nq,nr->qr", Y, W, optimize=False)
    logdet = float(np.sum(np.log(b)))
    if omega2 <= 0:
        return Q, logdet
    x = np.diff(t_s) / tc
    rho, q = np.exp(-x), -np.expm1(-2.0 * x)
    d = np.ones(m)
    d[1:] = 1.0 / q
    d[:-1] += rho**2 / q
    Mw = n[:, :, None] * n[:, None, :] / b[:, None, None]
    Mw[:, np.arange(3), np.arange(3)] += (d / omega2)[:, None]
    off = -rho / q / omega2
    ab = np.zeros((4, 3 * m))
    for a in range(3):
        for c in range(a, 3):
            ab[3 + a - c, c::3] = Mw[:, a, c]
        ab[0, 3 + a :: 3] = off
    cb = cholesky_banded(ab, lower=False, check_finite=False)
    logdet += 3 * m * math.log(omega2) + 3 * float(np.sum(np.log(q))) + 2 * float(np.sum(np.log(cb[3])))
    G = (n[:, :, None] * W[:, None, :]).reshape(3 * m, -1)
    H = cho_solve_banded((cb, False), G, check_finite=False)
    return Q - np.einsum("nq,nr->qr", G, H, optimize=False), logdet


def _reml(Q: FloatArray, logdet: float, p: int) -> float:
    A, bz, zz = Q[:p, :p], Q[:p, p], Q[p, p]
    try:
        La = np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        return -1e300
    theta = np.linalg.solve(A, bz)
    chi2 = max(float(zz - bz @ theta), 0.0)
    return -0.5 * (chi2 + logdet + 2.0 * float(np.sum(np.log(np.diag(La)))))


def scalar_wander(
    fit: ScalarFit, y_mean: FloatArray, g_local_m_s2: float, mid_s: FloatArray
) -> ScalarWander | None:
    """REML of the correlated wander for an orientation-free fit; ``None`` if it does not pay.

    :param fit: the orientation-free fit; :param y_mean: (m, 3) its window means.
    :param mid_s: (m,) window times (s), distinct.
    """
    t_all = np.asarray(mid_s, dtype=float).reshape(-1)
    m = fit.residuals_m_s2.shape[0]
    if t_all.shape != (m,) or not np.all(np.isfinite(t_all)):
        raise ValueError(f"window times must be finite (m,) = ({m},), got shape {t_all.shape}")
    grid = correlation_time_grid(t_all)
    if m <= 12 or not grid:
        return None
    order = np.argsort(t_all, kind="stable")
    t = t_all[order]
    if np.any(np.diff(t) <= 0):
        return None
    theta = np.concatenate([fit.bias, fit.L[_TRIL]])
    r, J, n, _ = _residual_and_jacobian(theta, np.asarray(y_mean, dtype=float), float(g_local_m_s2))
    b = fit.residual_sigma_m_s2**2
    Y = np.column_stack([J, r])[order]
    n, b = n[order], b[order]
    scale = float(np.median(b))

    def neg(u_log_omega: float, tc: float) -> float:
        return -_reml(*_quadratic(Y, b, n, t, scale * math.exp(u_log_omega), tc), 9)

    l0 = _reml(*_quadratic(Y, b, n, t, 0.0, 1.0), 9)
    best = (math.inf, 0.0, grid[0])
    for tc in grid:  # screening: ω² alone at each T_c
        res = minimize_scalar(lambda u, tc=tc: neg(u, tc), bounds=(-20.0, 12.0), method="bounded")
        if float(res.fun) < best[0]:
            best = (float(res.fun), float(res.x), tc)
    lo, hi = math.log(grid[0] / 2.0), math.log(grid[-1] * 2.0)
    res2 = minimize(
        lambda v: neg(v[0], math.exp(v[1])),
        np.array([best[1], math.log(best[2])]),
        method="Powell",
        bounds=[(-20.0, 12.0), (lo, hi)],
        options={"xtol": 1e-3, "ftol": 1e-6},
    )
    if float(res2.fun) < best[0]:
        best = (float(res2.fun), float(res2.x[0]), math.exp(float(res2.x[1])))
    lr = 2.0 * (-best[0] - l0)
    if lr <= WANDER_GATE:
        return None
    omega2 = scale * math.exp(best[1]) * t_factor(m - 9)
    Q, _ = _quadratic(Y, b, n, t, omega2, best[2])
    cov = np.linalg.inv(Q[:9, :9])
    return ScalarWander(
        cov=0.5 * (cov + cov.T), omega_m_s2=math.sqrt(omega2), corr_time_s=best[2], lr=float(lr)
    )
