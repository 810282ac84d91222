"""The slow wander of the static fit: per-channel bias wander correlated between windows.

On a long recording the windows share their errors (drift over the day, temperature);
independent window errors would then understate the sigmas. :func:`fit_slow_wander` fits,
by REML (``slow_noise``), each channel's wander variance τ² with an exponential correlation
time T_c and the pose scatter, and keeps it only when it beats independent window errors by
:data:`WANDER_GATE`. Used by ``static_fit`` and ``scalar_wander``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.stats import chi2 as chi2_dist

from bench.estimation.noise_reml import fit_noise
from bench.estimation.slow_noise import NoiseParams
from bench.estimation.static_design import design_rows
from bench.estimation.window_noise import t_factor

FloatArray = npt.NDArray[np.float64]

WANDER_GATE = float(chi2_dist.ppf(0.95, 1))
"""2 Δℓ_REML by which a wander correlated between windows must beat independent window
errors before the calibration's covariance uses it: the 5 % point of χ²₁ (3.84). The
independent model, when kept, understates the sigmas of a wander it missed (halves of
simulated day-long sessions with 2Δℓ of 4–6 disagreed by 4.4 sigma under the 1 % point), so
the gate errs towards the wander."""


@dataclass(frozen=True)
class SlowWander:
    """The correlated between-window model of :func:`fit_static` (``slow_noise``).

    :param noise: REML noise (τ² per channel, T_c, pose variance), inflated by ``t_factor``.
    :param lr: 2 Δℓ_REML of the correlated wander over independent window errors.
    :param J: (m, 3, 2) response of the window means to the pose angles.
    :param nugget: (m, 3, 3) independent excess per window kept from the independent fit.
    """

    noise: NoiseParams
    lr: float
    J: FloatArray
    nugget: FloatArray


def correlation_time_grid(mid_s: FloatArray) -> list[float]:
    """T_c (s) tried for the slow wander: 0.3, 1 and 3 times the span of the windows, and
    shorter ones down to twice the median window spacing, in steps of 4 (long recordings
    wander on scales much shorter than their span)."""
    t = np.sort(np.asarray(mid_s, dtype=float))
    span = float(t[-1] - t[0]) if t.size > 1 else 0.0
    if span <= 0:
        return []
    grid = [0.3 * span, span, 3.0 * span]
    spacing = float(np.median(np.diff(t)))
    tc = 0.3 * span / 4.0
    while tc >= 2.0 * spacing:
        grid.insert(0, tc)
        tc /= 4.0
    return grid


def pose_angles_response(K: FloatArray, f_m_s2: FloatArray) -> FloatArray:
    """(m, 3, 2) response of each window mean to two small tilt angles (rad) about axes
    perpendicular to its specific force: J_w = K |f_w| [u1 u2], so that J_w J_wᵀ =
    |f_w|² K (I − f̂ f̂ᵀ) Kᵀ (the shape of ``window_noise.pose_scatter``)."""
    f = np.asarray(f_m_s2, dtype=float)
    fn = np.linalg.norm(f, axis=1, keepdims=True)
    fh = f / fn
    e = np.eye(3)[np.argmin(np.abs(fh), axis=1)]
    u1 = np.cross(e, fh)
    u1 /= np.linalg.norm(u1, axis=1, keepdims=True)
    u2 = np.cross(fh, u1)
    return np.asarray(np.einsum("ik,wkq->wiq", K, fn[:, :, None] * np.stack([u1, u2], axis=2)), dtype=float)


def fit_slow_wander(
    f: FloatArray, y: FloatArray, V: FloatArray, K: FloatArray, mid_s: FloatArray, own: FloatArray, t: float
) -> SlowWander | None:
    """REML fit of a per-channel wander correlated between windows, with the pose scatter.

    τ² (3,), T_c and the pose variance are estimated by REML, T_c on
    :func:`correlation_time_grid` (screened, then refined), against the same model with
    T_c = 0 (independent). Returns ``None`` unless the correlated wander wins by
    :data:`WANDER_GATE`. ``own`` (3,) and ``t`` ((m/s²)², the pose variance) of the
    independent fit are the starting point.
    """
    m = f.shape[0]
    grid = correlation_time_grid(mid_s)
    if m <= 5 or not grid:
        return None
    X = design_rows(f).reshape(3 * m, 12)
    z = y.reshape(-1)
    J = pose_angles_response(K, f)
    floor = 1e-6 * float(np.median(np.diagonal(V, axis1=1, axis2=2)))
    g2 = float(np.median(np.sum(f * f, axis=1)))
    init = NoiseParams(tau2=np.maximum(own, floor), pose_var_rad2=max(t / g2, 1e-12))
    nugget = own[None, :, None] * np.eye(3)[None] * np.ones((m, 1, 1))
    fit = functools.partial(fit_noise, X, z, V, mid_s, J_pose=J, estimate_pose=True, init=init, fixed=nugget)
    _, f0 = fit(corr_times_s=[0.0])
    n1, f1 = fit(corr_times_s=grid, refine_corr_time=True)
    lr = 2.0 * (f1.loglik_reml - f0.loglik_reml)
    if lr <= WANDER_GATE or not np.any(n1.tau2 > 0):
        return None
    noise = NoiseParams(
        tau2=n1.tau2 * t_factor(m - 4),
        corr_time_s=n1.corr_time_s,
        pose_var_rad2=n1.pose_var_rad2 * t_factor(3 * (m - 4)),
    )
    return SlowWander(noise=noise, lr=float(lr), J=J, nugget=nugget)


def _exp_row_sums(mid_s: FloatArray, corr_time_s: float) -> FloatArray:
    """(m,) P 1 for P_ww' = exp(−|t_w − t_w'| / T_c), in O(m): with the times sorted and
    ρ_w = exp(−(t_w − t_{w−1}) / T_c), the sums from the left F_w = 1 + ρ_w F_{w−1} and from the
    right G_w = 1 + ρ_{w+1} G_{w+1} give (P 1)_w = F_w + G_w − 1."""
    order = np.argsort(mid_s, kind="stable")
    t = np.asarray(mid_s, dtype=float)[order]
    rho = np.exp(-np.diff(t) / corr_time_s)
    m = t.shape[0]
    left, right = np.ones(m), np.ones(m)
    for w in range(1, m):
        left[w] += rho[w - 1] * left[w - 1]
    for w in range(m - 2, -1, -1):
        right[w] += rho[w] * right[w + 1]
    out = np.empty(m)
    out[order] = left + right - 1.0
    return out


def run_mean_bias_cov(
    H: FloatArray,
    cov: FloatArray,
    solve: Callable[[FloatArray], FloatArray],
    noise: NoiseParams,
    mid_s: FloatArray,
) -> FloatArray:
    """(3, 3) covariance of the GLS bias against the run's mean bias b + s̄ (channel units²).

    The GLS estimate θ̂ = A z, A = C Hᵀ Σ⁻¹ (C = (Hᵀ Σ⁻¹ H)⁻¹ the fit's covariance, Σ the
    windows' covariance with the wander s_c(t_w) of each channel c, τ_c² P, P_ww' =
    exp(−|t_w − t_w'| / T_c)), has Cov(θ̂ − θ) = C: the error against the unit's long-run
    bias. Against the run's mean bias b_c + s̄_c, s̄_c = (1/m) Σ_w s_c(t_w), the bias error
    is A_b e − L s with L the mean over the windows, and (Cov(e, s) = Cov(s) = the wander part)

        C_run = C_bb − A_b Σ_s Lᵀ − L Σ_s A_bᵀ + L Σ_s Lᵀ,
        (Σ_s Lᵀ)_(w,c'),c = [c = c'] τ_c² (P 1)_w / m,   L Σ_s Lᵀ = diag(τ_c² 1ᵀ P 1 / m²),

    the form of ``dynamic_wander``'s ``cov_run_mean`` for window means (Papoulis & Pillai,
    4th ed., §9-5: the variance of a sample mean of a correlated process).

    :param H: (3m, 12) design rows, window-major. :param cov: (12, 12) C.
    :param solve: Y ↦ Σ⁻¹ Y for Y (3m, q) (``CovarianceFactor.solve``).
    :param noise: the wander (τ² (3,) channel units², T_c s > 0). :param mid_s: (m,) window times (s).
    """
    m = mid_s.shape[0]
    tau2 = np.asarray(noise.tau2, dtype=float)
    A_b = cov[:3] @ solve(H).T  # (3, 3m)
    s_lt = np.zeros((3 * m, 3))
    p1 = _exp_row_sums(mid_s, noise.corr_time_s)
    for c in range(3):
        s_lt[c::3, c] = tau2[c] * p1 / m
    cross = A_b @ s_lt
    out = cov[:3, :3] - cross - cross.T + np.diag(tau2 * float(np.sum(p1)) / m**2)
    return np.asarray(0.5 * (out + out.T), dtype=float)
