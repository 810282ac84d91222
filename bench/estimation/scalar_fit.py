"""Orientation-free (scalar) calibration: bias and lower-triangular K from |f| = g alone.

Without a table the orientation of each static window is unknown; each window only
says that the corrected specific force has the magnitude of local gravity:

    r_w(θ) = |L⁻¹ (ȳ_w − b)| − g = 0,    θ = [b_x, b_y, b_z, L_xx, L_yx, L_yy, L_zx, L_zy, L_zz]

(Tedaldi et al., ICRA 2014, as in imu_tk; ArduPilot ``AccelCalibrator``; Panahandeh et
al., IPIN 2010). Any K factors as K = L Q with L lower-triangular and Q orthogonal
(LQ decomposition), and |K⁻¹ d| = |L⁻¹ d|, so the data determine L = K up to a rotation
of the sensor frame: L Lᵀ = K Kᵀ. L is reported with a positive diagonal.

Weighted Gauss-Newton (scipy ``least_squares``, analytic Jacobian):

    ∂r/∂b = −nᵀ L⁻¹,   ∂r/∂L_jk = −(L⁻ᵀ n)_j u_k,   u = L⁻¹ (ȳ − b), n = u / |u|,

with the variance of r_w from the window-mean covariance V_w: σ_w² = nᵀ L⁻¹ V_w L⁻ᵀ n,
plus an additive between-window variance (Paule-Mandel, as in ``window_noise``) when
the windows scatter more than their noise. Covariance (Jᵀ W J)⁻¹, each variance at least the
sandwich's over windows (White's HC1), which carries a scatter that differs between windows
(motion in the windows near one pose) with its leverage; a fixed error that follows the pose
is absorbed into b and L and reaches neither (docs/noise-model.md). Needs ≥ 9 windows,
and more (imu_tk asks for ≥ 12, well spread) for a useful redundancy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from bench.estimation.window_noise import solve_decreasing, t_factor

FloatArray = npt.NDArray[np.float64]

MIN_WINDOWS = 9
_TRIL = np.tril_indices(3)
PARAMETER_NAMES: tuple[str, ...] = ("b_x", "b_y", "b_z", "L_xx", "L_yx", "L_yy", "L_zx", "L_zy", "L_zz")


@dataclass(frozen=True)
class ScalarFit:
    """Result of :func:`fit_scalar`.

    :param bias: (3,) b in channel units.
    :param L: (3, 3) lower-triangular scale matrix (channel unit per m/s²), K up to rotation.
    :param cov: (9, 9) covariance in the order of :data:`PARAMETER_NAMES`.
    :param residuals_m_s2: (m,) |L⁻¹(ȳ − b)| − g per window (m/s²).
    :param residual_sigma_m_s2: (m,) standard deviation of each residual under the noise model.
    :param chi2: Σ r² / σ_w² against the within-window noise alone.
    :param dof: m − 9.
    :param excess_var_m_s2: additive between-window variance (m/s²)².
    :param sandwich_cov: (9, 9) the sandwich covariance over windows (:func:`window_sandwich`);
        ``cov``'s variances are at least its.
    """

    bias: FloatArray
    L: FloatArray
    cov: FloatArray
    residuals_m_s2: FloatArray
    residual_sigma_m_s2: FloatArray
    chi2: float
    dof: int
    excess_var_m_s2: float
    sandwich_cov: FloatArray

    @property
    def sigma(self) -> FloatArray:
        """(9,) one-sigma uncertainties in the order of :data:`PARAMETER_NAMES`."""
        return np.sqrt(np.diag(self.cov))

    @property
    def L_sigma(self) -> FloatArray:
        """(3, 3) one-sigma uncertainty of L (0 above the diagonal, where L is 0 by definition)."""
        s = np.zeros((3, 3))
        s[_TRIL] = self.sigma[3:]
        return s


def _unpack(theta: FloatArray) -> tuple[FloatArray, FloatArray]:
    L = np.zeros((3, 3))
    L[_TRIL] = theta[3:]
    return theta[:3], L


def _residual_and_jacobian(theta: FloatArray, y: FloatArray, g: float) -> tuple[FloatArray, ...]:
    b, L = _unpack(theta)
    Linv = np.linalg.inv(L)
    u = (y - b) @ Linv.T  # (m, 3)
    nu = np.linalg.norm(u, axis=1)
    n = u / nu[:, None]
    r = nu - g
    a = n @ Linv  # (m, 3): (L⁻ᵀ n)ᵀ = nᵀ L⁻¹
    J = np.empty((y.shape[0], 9))
    J[:, :3] = -a
    J[:, 3:] = -(a[:, :, None] * u[:, None, :])[:, _TRIL[0], _TRIL[1]]
    return np.asarray(r, dtype=float), J, np.asarray(n, dtype=float), np.asarray(Linv, dtype=float)


def _residual_variance(theta: FloatArray, y: FloatArray, V: FloatArray, g: float) -> FloatArray:
    """(m,) σ_w² = nᵀ L⁻¹ V_w L⁻ᵀ n, the variance of r_w from the window-mean noise."""
    _, _, n, Linv = _residual_and_jacobian(theta, y, g)
    a = n @ Linv
    return np.asarray(np.einsum("wi,wij,wj->w", a, V, a), dtype=float)


def _weighted_residual(theta: FloatArray, y: FloatArray, g: float, w: FloatArray) -> FloatArray:
    return _residual_and_jacobian(theta, y, g)[0] * w


def _weighted_jacobian(theta: FloatArray, y: FloatArray, g: float, w: FloatArray) -> FloatArray:
    return _residual_and_jacobian(theta, y, g)[1] * w[:, None]


def _excess(r: FloatArray, sig2: FloatArray, dof: int) -> float:
    """Paule-Mandel between-window variance: Σ r² / (σ² + τ²) = dof, 0 if already below."""
    if dof <= 0:
        return 0.0
    return solve_decreasing(lambda t: float(np.sum(r**2 / (sig2 + t))), dof, float(np.median(sig2)))


def window_sandwich(cov: FloatArray, Jw: FloatArray, rw: FloatArray) -> FloatArray:
    """(p, p) sandwich covariance over windows (White's HC1): the windows' weighted residuals
    ``rw`` (m,) stand in for their own variance, so a misfit that differs between windows
    (motion in some, errors that follow the pose) reaches the parameters with its leverage.

        S = C (Σ_w j_w j_wᵀ r̃_w²) C · m / (m − p),   C = (J̃ᵀ J̃)⁻¹,  j_w the rows of ``Jw`` (m, p).
    """
    m, p = Jw.shape
    meat = (Jw * rw[:, None]).T @ (Jw * rw[:, None])
    return np.asarray(cov @ meat @ cov * (m / max(m - p, 1)), dtype=float)


def floor_by_sandwich(cov: FloatArray, sandwich: FloatArray) -> FloatArray:
    """``cov`` (p, p) scaled so that each variance is at least the sandwich's (correlations kept):
    D C D with D = diag(max(1, √(S_ii / C_ii)))."""
    d = np.sqrt(np.maximum(1.0, np.diag(sandwich) / np.diag(cov)))
    return np.asarray(cov * np.outer(d, d), dtype=float)


def _initial_guess(y: FloatArray, g: float) -> FloatArray:
    """Algebraic ellipsoid fit (yᵀ A y + cᵀ y + d = 0, smallest singular vector) -> b, L."""
    c0, s0 = y.mean(axis=0), y.std(axis=0).max()
    z = (y - c0) / s0
    i, j = np.triu_indices(3)
    D = np.column_stack([z[:, i] * z[:, j], z, np.ones(len(z))])
    v = np.linalg.svd(D)[2][-1]
    A = np.zeros((3, 3))
    A[i, j] = v[:6]
    A = 0.5 * (A + A.T)
    if np.trace(A) < 0:
        A, v = -A, -v
    center = np.linalg.solve(-2 * A, v[6:9])
    k = center @ A @ center - v[9]  # (z − c)ᵀ A (z − c) = k
    M = A / k  # (z − c)ᵀ M (z − c) = 1; M must be positive definite
    if not np.all(np.linalg.eigvalsh(M) > 0):
        raise ValueError("the window means do not lie on an ellipsoid: cannot start the scalar calibration")
    # y − b = s0 (z − c) and |L⁻¹(y − b)| = g  ⇒  L Lᵀ = s0² M⁻¹ / g²
    L = np.linalg.cholesky(np.linalg.inv(M)) * s0 / g
    return np.concatenate([c0 + s0 * center, L[_TRIL]])


def fit_scalar(y_mean: FloatArray, y_cov: FloatArray, g_local_m_s2: float) -> ScalarFit:
    """Fit b and lower-triangular L so that |L⁻¹(ȳ_w − b)| = g in every static window.

    :param y_mean: (m, 3) window means (channel units), m ≥ 9, well-spread orientations.
    :param y_cov: (m, 3, 3) covariance of each window mean.
    :param g_local_m_s2: local gravity (m/s²).
    :returns: :class:`ScalarFit`.
    :raises ValueError: fewer than 9 windows, non-finite input, or orientations too
        poorly spread to determine the 9 parameters.
    """
    y = np.asarray(y_mean, dtype=float)
    V = np.asarray(y_cov, dtype=float)
    m = y.shape[0] if y.ndim == 2 else 0
    if y.shape != (m, 3) or V.shape != (m, 3, 3):
        raise ValueError(f"expected window means (m, 3) and covariances (m, 3, 3), got {y.shape}, {V.shape}")
    if m < MIN_WINDOWS:
        raise ValueError(
            f"the orientation-free calibration needs at least {MIN_WINDOWS} static windows in "
            f"well-spread orientations (9 parameters from |f| = g alone), got {m}"
        )
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(V))):
        raise ValueError("window means or covariances are not finite")
    g = float(g_local_m_s2)
    theta = _initial_guess(y, g)
    tau2 = 0.0
    for _ in range(3):  # weights depend on the estimate: refit with updated weights
        w = 1.0 / np.sqrt(_residual_variance(theta, y, V, g) + tau2)
        theta = least_squares(
            _weighted_residual,
            theta,
            jac=_weighted_jacobian,
            args=(y, g, w),
            method="lm",
            xtol=1e-15,
            ftol=1e-15,
        ).x
        tau2 = _excess(_residual_and_jacobian(theta, y, g)[0], _residual_variance(theta, y, V, g), m - 9)
    tau2 *= t_factor(m - 9)
    r, J, _, _ = _residual_and_jacobian(theta, y, g)
    sig2 = _residual_variance(theta, y, V, g)
    Jw = J / np.sqrt(sig2 + tau2)[:, None]
    s = np.linalg.svd(Jw, compute_uv=False)
    if s[-1] < 1e-10 * s[0]:
        raise ValueError(
            "the static windows' orientations are too poorly spread to determine bias and scale "
            "from |f| = g alone (Jacobian rank-deficient): add orientations covering all axes"
        )
    cov: FloatArray = np.asarray(np.linalg.inv(Jw.T @ Jw), dtype=float)
    sandwich = window_sandwich(cov, Jw, r / np.sqrt(sig2 + tau2))
    cov = floor_by_sandwich(cov, sandwich)
    b, L = _unpack(theta)
    sign = np.sign(np.diag(L))  # L Lᵀ is unchanged by flipping a column's sign
    L = L * sign[None, :]
    flip = np.outer(
        np.concatenate([np.ones(3), sign[_TRIL[1]]]), np.concatenate([np.ones(3), sign[_TRIL[1]]])
    )
    cov, sandwich = cov * flip, sandwich * flip
    return ScalarFit(
        bias=b,
        L=L,
        cov=0.5 * (cov + cov.T),
        residuals_m_s2=r,
        residual_sigma_m_s2=np.sqrt(sig2 + tau2),
        chi2=float(np.sum(r**2 / sig2)),
        dof=m - 9,
        excess_var_m_s2=float(tau2),
        sandwich_cov=0.5 * (sandwich + sandwich.T),
    )
