"""Gaussian likelihood of the stacked window means: covariance, GLS, REML noise estimation.

Used by the calibration (``static_fit``) and the diagnosis (``bench.diagnosis.likelihood``).

Observation vector z = y.reshape(-1) (3m,), window-major. Covariance (channel units²):

    C = blockdiag_w(V_w + F + σ_p² J_w J_wᵀ + Σ_i ε_i² e_i e_iᵀ) + Σ_i τ_i² (P ⊗ e_i e_iᵀ),
    P_ww' = exp(−|t_w − t_w'| / T_c)   (P = I for T_c = 0)

- V_w: the window mean's covariance from its own samples (batch means; ``window_noise``);
- τ_i², T_c: slow noise of channel i that a window cannot see in itself (bias wander with
  correlation time T_c; T_c = 0: independent from window to window);
- σ_p²: variance of a random pose error per window (two angles, rad²), J_w (3, 2) the
  response of the window mean to those angles (``pose_error``);
- ε_i²: an optional excess of channel i alone, independent from window to window (a misfit
  on one channel that the diagnosis holds as noise, ``bench.diagnosis.head_to_head_stage``);
  estimated by REML only on the channels asked for;
- F: an optional fixed extra (e.g. free orientation in an orientation-free diagnosis).

Every evaluation is O(m) (``window_covariance``: the wander as a Markov state, Woodbury
with a banded Cholesky factor), so a 3000-window recording costs what a 12-window one does,
times m.

For a fixed design X (3m, p), the generalised least-squares estimate and the ML and
REML log-likelihoods (Harville, JASA 72 (1977) 320, eq. 4.3) are

    θ̂ = (Xᵀ C⁻¹ X)⁻¹ Xᵀ C⁻¹ z,   r = z − X θ̂,   χ² = rᵀ C⁻¹ r,
    −2 ℓ_ML   = χ² + ln|C| + n ln 2π,
    −2 ℓ_REML = χ² + ln|C| + ln|Xᵀ C⁻¹ X| + (n − p) ln 2π.

The noise parameters (τ², T_c, σ_p², ε²) are estimated by maximising ℓ_REML, which, unlike
ℓ_ML, is not biased low by the p fitted parameters (with 36 observations and 12–20
parameters the difference is large): ``noise_reml.fit_noise``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
from scipy.linalg import cho_factor, cho_solve
from scipy.linalg.lapack import dpotrf, dpotrs

from bench.estimation.window_covariance import (
    FixedQuadratic,
    WindowCovariance,
)

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class NoiseParams:
    """Noise parameters beyond the windows' own scatter.

    :param tau2: (3,) slow-noise variance per channel (channel units²).
    :param corr_time_s: its correlation time T_c (s); 0 = independent between windows.
    :param pose_var_rad2: random pose-error variance per angle (rad²); 0 = none.
    :param excess_var: (3,) ε_i², each channel's own excess from window to window (channel
        units²), or ``None`` (none).
    :param excess_channels: the channels whose ε_i² is a free parameter (``noise_reml.fit_noise``
        re-estimates them when this is its ``init``).
    """

    tau2: FloatArray
    corr_time_s: float = 0.0
    pose_var_rad2: float = 0.0
    n_tau: int = 3
    excess_var: FloatArray | None = None
    excess_channels: tuple[int, ...] = ()

    @property
    def n_free(self) -> int:
        """Number of estimated noise parameters counted in the BIC."""
        return self.n_tau + (1 if self.corr_time_s > 0 else 0) + len(self.excess_channels)


@dataclass(frozen=True)
class GlsFit:
    """GLS fit of one design under one covariance.

    :param theta: (p,) estimates; :param cov: (p, p) their covariance (Xᵀ C⁻¹ X)⁻¹.
    :param resid: (3m,) residuals z − X θ̂; :param chi2: rᵀ C⁻¹ r.
    :param loglik_ml: ℓ_ML; :param loglik_reml: ℓ_REML.
    """

    theta: FloatArray
    cov: FloatArray
    resid: FloatArray
    chi2: float
    loglik_ml: float
    loglik_reml: float


def correlation(mid_s: FloatArray, corr_time_s: float) -> FloatArray:
    """(m, m) P_ww' = exp(−|t_w − t_w'| / T_c); the identity for T_c = 0."""
    m = mid_s.shape[0]
    if corr_time_s <= 0:
        return np.eye(m)
    return np.exp(-np.abs(mid_s[:, None] - mid_s[None, :]) / corr_time_s)


def window_covariance(
    V: FloatArray,
    mid_s: FloatArray,
    noise: NoiseParams,
    J_pose: FloatArray | None = None,
    fixed: FloatArray | None = None,
) -> WindowCovariance:
    """C of the module docstring in its O(m) form (``window_covariance.WindowCovariance``).

    :param V: (m, 3, 3) window-mean covariances; :param mid_s: (m,) window times (s).
    :param J_pose: (m, 3, 2) pose response per window, needed when ``pose_var_rad2 > 0``.
    :param fixed: (m, 3, 3) fixed extra per window, or ``None``.
    """
    blocks = np.array(V, dtype=float, copy=True)
    if fixed is not None:
        blocks = blocks + fixed
    if noise.pose_var_rad2 > 0:
        if J_pose is None:
            raise ValueError("a pose-error variance needs the pose response J_pose")
        blocks = blocks + noise.pose_var_rad2 * np.einsum("wik,wjk->wij", J_pose, J_pose)
    if noise.excess_var is not None:
        for i in range(3):
            blocks[:, i, i] += noise.excess_var[i]
    return WindowCovariance(
        blocks=blocks,
        tau2=np.asarray(noise.tau2, dtype=float),
        corr_time_s=float(noise.corr_time_s),
        mid_s=np.asarray(mid_s, dtype=float),
    )


def covariance(
    V: FloatArray,
    mid_s: FloatArray,
    noise: NoiseParams,
    J_pose: FloatArray | None = None,
    fixed: FloatArray | None = None,
) -> FloatArray:
    """(3m, 3m) covariance C of the module docstring as a dense matrix (small m, checks).

    Arguments as :func:`window_covariance`.
    """
    return window_covariance(V, mid_s, noise, J_pose, fixed).dense()


def gls(
    X: FloatArray,
    z: FloatArray,
    C: FloatArray | WindowCovariance,
    binv_xz: FloatArray | None = None,
    fixed_xz: FixedQuadratic | None = None,
) -> GlsFit:
    """Generalised least squares of z on X with covariance C (module docstring).

    ``C`` is a dense (n, n) matrix or a :class:`WindowCovariance`; then everything comes
    from the (p+1, p+1) matrix Q = [X z]ᵀ C⁻¹ [X z] in O(m) (θ̂ = Q_XX⁻¹ Q_Xz,
    χ² = Q_zz − Q_zXᵀ θ̂), and ``binv_xz`` (B⁻¹ [X z], which does not depend on the
    wander) may be passed to save its product, or ``fixed_xz`` (B⁻¹ [X z] and
    [X z]ᵀ B⁻¹ [X z], ``window_covariance.fixed_quadratic``) to save both.

    :raises ValueError: C not positive definite or X rank-deficient under C.
    """
    n, p = X.shape
    if isinstance(C, WindowCovariance):
        fac = C.factor()
        logdet_c = fac.logdet
        if fixed_xz is not None:
            Q = fac.quadratic_fixed(fixed_xz)
        else:
            Q = fac.quadratic(np.column_stack([X, z]), binv_xz)
        A, b, zz = Q[:p, :p], Q[:p, p], float(Q[p, p])
    else:
        try:
            cf = cho_factor(C, lower=True)
        except np.linalg.LinAlgError as exc:
            raise ValueError("noise covariance is not positive definite") from exc
        logdet_c = 2.0 * float(np.sum(np.log(np.diag(cf[0]))))
        CiX = cho_solve(cf, X)
        A, b, zz = X.T @ CiX, CiX.T @ z, float(z @ cho_solve(cf, z))
    # LAPACK's Cholesky of the (p, p) A directly: scipy's cho_factor/cho_solve wrappers cost
    # more than the factorisation itself at this size, in a search that calls this thousands of times
    if not np.all(np.isfinite(A)):
        raise ValueError("the GLS normal matrix is not finite")
    La, info = dpotrf(A, lower=1, clean=1)
    if info != 0:
        raise ValueError("design is rank-deficient: some parameters cannot be determined")
    theta = dpotrs(La, b, lower=1)[0]
    r = z - X @ theta
    chi2 = max(zz - float(b @ theta), 0.0)  # rᵀ C⁻¹ r = zᵀC⁻¹z − θ̂ᵀ XᵀC⁻¹z
    logdet_a = 2.0 * float(np.sum(np.log(np.diag(La))))
    ml = -0.5 * (chi2 + logdet_c + n * math.log(2 * math.pi))
    reml = -0.5 * (chi2 + logdet_c + logdet_a + (n - p) * math.log(2 * math.pi))
    cov = dpotrs(La, np.eye(p), lower=1)[0]
    return GlsFit(theta=theta, cov=0.5 * (cov + cov.T), resid=r, chi2=chi2, loglik_ml=ml, loglik_reml=reml)


def without_pose(noise: NoiseParams) -> NoiseParams:
    """The same noise with the random pose error removed."""
    return replace(noise, pose_var_rad2=0.0)


def without_excess(noise: NoiseParams) -> NoiseParams:
    """The same noise without the channels' own excess (none, and none to estimate)."""
    return replace(noise, excess_var=None, excess_channels=())
