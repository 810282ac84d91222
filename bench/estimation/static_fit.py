"""Multi-position static calibration with known orientations: bias + full 3×3 K per channel.

Model (tumble test, DESIGN.md §1): the mean of static window w on channel i is

    y_w,i = b_i + K_i · f_w + e_w,i,    Var(e_w,i) = V_w,ii + τ_i²

with f_w (3,) the specific force from the table kinematics (m/s²), V_w the covariance of
the window mean from its own samples (``window_noise``) and τ_i² an additive
between-window variance (pose errors, bias wander between windows) estimated from the
scatter of the windows about the fit (``window_noise.between_window_variance``). Each channel is the
weighted linear least-squares problem X θ_i ≈ y_i with X = [1 f_x f_y f_z] (m, 4).

Parameter order of ``StaticFit.cov`` (12, 12), SI/channel units:

    [b_x, b_y, b_z, K_xx, K_xy, K_xz, K_yx, K_yy, K_yz, K_zx, K_zy, K_zz]

Cross-channel blocks carry the within-window correlation of the channels:
Cov(θ_i, θ_j) = A_i C_ij A_jᵀ, A_i = (Xᵀ W_i X)⁻¹ Xᵀ W_i, C_ij = diag_w(V_w,ij) + δ_ij τ_i² I.
For white noise the estimator reaches the Cramér-Rao bound σ²/L · (XᵀX)⁻¹
(research-peers.md §4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.window_noise import between_window_variance

FloatArray = npt.NDArray[np.float64]

PARAMETER_NAMES: tuple[str, ...] = (
    "b_x", "b_y", "b_z",
    "K_xx", "K_xy", "K_xz",
    "K_yx", "K_yy", "K_yz",
    "K_zx", "K_zy", "K_zz",
)  # fmt: skip
"""Names of the 12 parameters in the order of ``StaticFit.cov``."""


@dataclass(frozen=True)
class StaticFit:
    """Result of :func:`fit_static`.

    :param bias: (3,) b in channel units.
    :param K: (3, 3) scale/misalignment, channel unit per m/s²: raw = b + K f.
    :param cov: (12, 12) covariance in the order of :data:`PARAMETER_NAMES`.
    :param residuals: (m, 3) y − b − K f per window, channel units.
    :param normalized_residuals: (m, 3) residuals over their own standard deviation
        √(v_w,i (1 − h_w,i)) under the full noise model (≈ N(0, 1) when the model holds).
    :param chi2: Σ r² / V_w,ii against the within-window noise alone (tests whether the
        windows scatter more than their own samples explain).
    :param dof: 3 (m − 4).
    :param excess_var: (m, 3) variance added between windows, channel units squared.
    :param noise_model: short description of the noise model used.
    """

    bias: FloatArray
    K: FloatArray
    cov: FloatArray
    residuals: FloatArray
    normalized_residuals: FloatArray
    chi2: float
    dof: int
    excess_var: FloatArray
    noise_model: str

    @property
    def params(self) -> FloatArray:
        """(12,) parameter vector in the order of :data:`PARAMETER_NAMES`."""
        return np.concatenate([self.bias, self.K.ravel()])

    @property
    def sigma(self) -> FloatArray:
        """(12,) one-sigma uncertainties in the order of :data:`PARAMETER_NAMES`."""
        return np.sqrt(np.diag(self.cov))

    @property
    def bias_sigma(self) -> FloatArray:
        """(3,) one-sigma uncertainty of the bias."""
        return self.sigma[:3]

    @property
    def K_sigma(self) -> FloatArray:
        """(3, 3) one-sigma uncertainty of K."""
        return self.sigma[3:].reshape(3, 3)


_COLUMN_NAMES = ("bias", "K[:,0] (response to f_x)", "K[:,1] (response to f_y)", "K[:,2] (response to f_z)")
RCOND_LIMIT = 1e-6
"""Smallest singular value of the normalised design [1 f/|f|] relative to the largest."""


def _relation_text(v: FloatArray, f_scale: float) -> str:
    """Describe the null vector v of [1 f/f_scale] as the relation every window satisfies."""
    coef = v[1:] / f_scale
    k = int(np.argmax(np.abs(coef)))
    coef, const = coef / coef[k], -v[0] / coef[k]
    const = 0.0 if abs(const) < 1e-9 * f_scale else float(const)
    axes = ("f_x", "f_y", "f_z")
    terms = [
        f"{c:+.3g}·{axes[j]}" if j != k else axes[j] for j, c in enumerate(coef) if abs(c) > 1e-6 or j == k
    ]
    lhs = " ".join(terms) if len(terms) > 1 else terms[0]
    rhs = "0" if const == 0.0 else f"{const:+.4g} m/s²"
    return f"{lhs.replace('+1·', '+').replace('-1·', '-')} = {rhs}"


def check_design(f_m_s2: FloatArray) -> FloatArray:
    """Design matrix X = [1 f_x f_y f_z] (m, 4), refused if it cannot identify the parameters.

    The 12 parameters are identifiable iff X has full column rank 4, i.e. the specific
    forces do not all lie on one plane (a constant component is a plane too). The null
    space of the column-normalised X names the confounded parameters and the relation
    the orientations share.

    :param f_m_s2: (m, 3) specific force per window (m/s²).
    :returns: (m, 4) design matrix.
    :raises ValueError: fewer than 4 windows, or rank/conditioning too low; the message
        names the parameters that cannot be determined.
    """
    f = np.asarray(f_m_s2, dtype=float)
    m = f.shape[0]
    if m < 4:
        raise ValueError(f"at least 4 static windows with well-spread orientations are needed, got {m}")
    X = np.column_stack([np.ones(m), f])
    f_scale = float(np.median(np.linalg.norm(f, axis=1)))
    if not f_scale > 0:
        raise ValueError("specific force is zero in most windows: no gravity reference to calibrate against")
    Xn = np.column_stack([np.ones(m), f / f_scale])
    _, s, Vt = np.linalg.svd(Xn, full_matrices=False)
    null = Vt[s < RCOND_LIMIT * s[0]]
    if null.shape[0]:
        parts = []
        for v in null:
            names = [_COLUMN_NAMES[j] for j in np.flatnonzero(np.abs(v) > 0.05 * np.max(np.abs(v)))]
            joined = " and ".join(names)
            what = f"{joined} are confounded" if len(names) > 1 else f"{joined} cannot be determined"
            parts.append(f"{what}: every orientation has {_relation_text(v, f_scale)}")
        raise ValueError(
            "degenerate orientation set, the model cannot be identified on any channel: "
            + "; ".join(parts)
            + " (use ≥ 4 orientations whose gravity directions do not lie on one plane)"
        )
    return X


def _validate(f_m_s2: FloatArray, y_mean: FloatArray, y_cov: FloatArray) -> tuple[FloatArray, ...]:
    f = np.asarray(f_m_s2, dtype=float)
    y = np.asarray(y_mean, dtype=float)
    V = np.asarray(y_cov, dtype=float)
    m = f.shape[0] if f.ndim == 2 else -1
    if f.shape != (m, 3) or y.shape != (m, 3) or V.shape != (m, 3, 3):
        raise ValueError(
            f"expected f (m, 3), window means (m, 3), covariances (m, 3, 3); "
            f"got {f.shape}, {y.shape}, {V.shape}"
        )
    for name, a in (("specific force", f), ("window mean", y), ("window covariance", V)):
        if not np.all(np.isfinite(a)):
            w = int(np.argwhere(~np.isfinite(a))[0, 0])
            raise ValueError(f"{name} of window {w} is not finite")
    d = np.diagonal(V, axis1=1, axis2=2)
    if np.any(d <= 0):
        w = int(np.argwhere(d <= 0)[0, 0])
        raise ValueError(f"window {w}: variance of the mean must be positive, got {d[w].tolist()}")
    return f, y, V


def _wls(X: FloatArray, y: FloatArray, var: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Weighted LS θ and A = (Xᵀ W X)⁻¹ Xᵀ W for one channel (W = diag(1/var))."""
    Xw = X / var[:, None]
    A = np.asarray(np.linalg.solve(X.T @ Xw, Xw.T), dtype=float)
    return np.asarray(A @ y, dtype=float), A


def fit_static(
    f_m_s2: FloatArray, y_mean: FloatArray, y_cov: FloatArray, *, between_window: bool = True
) -> StaticFit:
    """Fit bias and full K of a triad to static window means with known specific force.

    :param f_m_s2: (m, 3) specific force in the sensor frame per window (m/s²),
        e.g. Rᵀ [0, 0, g] from the table angles.
    :param y_mean: (m, 3) window means of the raw channels (channel units).
    :param y_cov: (m, 3, 3) covariance of each window mean (``window_noise``).
    :param between_window: estimate the additive between-window variance τ² (default);
        ``False`` trusts the within-window covariances alone.
    :returns: :class:`StaticFit`.
    :raises ValueError: bad shapes or values, fewer than 4 windows, or an orientation set
        that cannot identify all 12 parameters (the message names them).
    """
    f, y, V = _validate(f_m_s2, y_mean, y_cov)
    m = f.shape[0]
    X = check_design(f)
    var_within = np.diagonal(V, axis1=1, axis2=2)  # (m, 3)

    def solve(tau2: FloatArray) -> tuple[FloatArray, list[FloatArray]]:
        theta = np.empty((3, 4))
        A = []
        for i in range(3):
            theta[i], Ai = _wls(X, y[:, i], var_within[:, i] + tau2[:, i])
            A.append(Ai)
        return theta, A

    theta, _ = solve(np.zeros((m, 3)))
    tau2 = np.zeros((m, 3))
    if between_window and m > 4:
        for _ in range(2):  # the pose-scatter shape depends on K: one refinement suffices
            tau2 = between_window_variance(X, y, var_within, theta[:, 1:])
            theta, _ = solve(tau2)
    theta, A = solve(tau2)

    cov = np.zeros((12, 12))
    idx = [[i, 3 + 3 * i, 4 + 3 * i, 5 + 3 * i] for i in range(3)]
    for i in range(3):
        for j in range(3):
            C = np.diag(V[:, i, j] + (tau2[:, i] if i == j else 0.0))
            cov[np.ix_(idx[i], idx[j])] = A[i] @ C @ A[j].T

    resid = y - X @ theta.T
    var_total = var_within + tau2
    lev = np.stack([np.einsum("wk,kw->w", X, A[i]) for i in range(3)], axis=1)  # h_w,i
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = np.sqrt(np.clip(var_total * (1.0 - lev), 0.0, None))
        norm_resid = np.where(denom > 0, resid / denom, 0.0)
    chi2 = float(np.sum(resid**2 / var_within))
    tau_txt = ", ".join(f"{np.sqrt(t):.3g}" for t in tau2.mean(axis=0))
    model = (
        "window means: batch-means covariance from each window's samples; "
        f"between windows: additive pose + channel scatter, rms sigma = [{tau_txt}] channel units"
        if between_window
        else "window means: batch-means covariance from each window's samples"
    )
    return StaticFit(
        bias=theta[:, 0].copy(),
        K=theta[:, 1:].copy(),
        cov=0.5 * (cov + cov.T),
        residuals=resid,
        normalized_residuals=norm_resid,
        chi2=chi2,
        dof=3 * (m - 4),
        excess_var=tau2,
        noise_model=model,
    )
