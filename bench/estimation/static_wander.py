"""The slow wander of the static fit: per-channel bias wander correlated between windows.

On a long recording the windows share their errors (drift over the day, temperature);
independent window errors would then understate the sigmas. :func:`fit_slow_wander` fits,
by REML (``slow_noise``), each channel's wander variance τ² with an exponential correlation
time T_c and the pose scatter, and keeps it only when it beats independent window errors by
:data:`WANDER_GATE`. Used by ``static_fit`` and ``scalar_wander``.
"""

from __future__ import annotations

import functools
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
