"""Multi-position static calibration with known orientations: bias + full 3×3 K per channel.

Model (tumble test, docs/methods.md §1): the mean of static window w is

    y_w = b + K f_w + e_w,    Cov(e_w) = S_w = V_w + t · K (I − f̂_w f̂_wᵀ) Kᵀ + diag(τ²)

with f_w (3,) the specific force from the table kinematics (m/s²), V_w (3, 3) the
covariance of the window mean from its own samples (``window_noise``), t (m/s²)² the
variance of a random pose error (the unit tilted by a small angle δ_w: error K (δ_w × f_w),
perpendicular to gravity and common to the three channels, ``window_noise.pose_scatter``)
and τ_i² each channel's own between-window excess (bias wander). The 12 parameters are the
generalised least-squares solution over all channels at once (θ = (Σ Hᵀ S⁻¹ H)⁻¹ Σ Hᵀ S⁻¹ y,
H_w = [I₃, I₃ ⊗ f_wᵀ]): the pose error's cross-channel covariance is kept, so a window's
reading along gravity (the |g| direction, free of first-order pose error) is weighted by
its own noise and the perpendicular readings by the pose scatter. t and τ² are
moment (Paule-Mandel) estimates from the scatter of the windows about the fit.

Parameter order of ``StaticFit.cov`` (12, 12), SI/channel units:

    [b_x, b_y, b_z, K_xx, K_xy, K_xz, K_yx, K_yy, K_yz, K_zx, K_zy, K_zz]

Cov(θ) = (Σ_w H_wᵀ S_w⁻¹ H_w)⁻¹. For white noise and no pose error the estimator reaches the
Cramér-Rao bound σ²/L · (XᵀX)⁻¹ per channel (the linear Gaussian model: Kay, Fundamentals
of Statistical Signal Processing I (1993), Theorem 4.1).

The parameter order, the rows H_w and the identifiability check are in ``static_design``;
the slow wander correlated between windows in ``static_wander``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.dynamic_batch import BiasReference
from bench.estimation.slow_noise import gls, window_covariance
from bench.estimation.static_design import check_design, design_rows
from bench.estimation.static_wander import fit_slow_wander, run_mean_bias_cov
from bench.estimation.window_noise import (
    known_share,
    own_channel_variance,
    pm_statistic,
    pose_scatter,
    solve_decreasing,
    t_factor,
)

FloatArray = npt.NDArray[np.float64]


UNGATED_MIN_DOF = 5
"""Residual degrees of freedom per channel (m − 4) from which each channel's own excess is
the plain Paule-Mandel estimate, without the 95 % χ² gate. With 8 (static-12) the gate dropped
an excess as large as the windows' own noise more often than not (with 3 arc-minute placement
errors at 41 min: K z RMS 1.22 and |z| to 5.5 gated, 0.94 and 3.5 without, docs/noise-model.md).
Below 5 the variance of Student's t_ν that scales the estimate is not finite or barely so
(``t_factor``: 3 for ν ≤ 4), and on a 6-window tumble (ν = 2) an ungated excess moved the
weights so far that the |g| check after calibration scattered 66 times more."""


@dataclass(frozen=True)
class StaticFit:
    """Result of :func:`fit_static`.

    :param bias: (3,) b in channel units.
    :param K: (3, 3) scale/misalignment, channel unit per m/s²: raw = b + K f.
    :param cov: (12, 12) covariance in the order of :data:`~.static_design.PARAMETER_NAMES`.
    :param residuals: (m, 3) y − b − K f per window, channel units.
    :param normalized_residuals: (m, 3) residuals over their own standard deviation
        √((S_w − H_w Cov(θ) H_wᵀ)_ii) under the full noise model (≈ N(0, 1) when the model holds).
    :param chi2: Σ r² / V_w,ii against the within-window noise alone (tests whether the
        windows scatter more than their own samples explain).
    :param dof: 3 (m − 4).
    :param excess_var: (m, 3) diagonal of the between-window covariance added to each
        window (pose scatter + own excess), channel units squared.
    :param noise_model: short description of the noise model used.
    :param bias_reference: what the bias sigma describes
        (:data:`~.dynamic_batch.BiasReference`): ``"long_run"`` when the correlated wander is
        in the covariance (its GLS counts the wander's average over the session), else
        ``"run_mean"`` (independent window errors: on a 12-window tumble with a 40 µg / 200 s
        wander the error against the long-run bias is 1.7–2.0× the sigma, docs/noise-model.md).
    :param bias_sigma_run_mean: (3,) the bias sigma against the run's mean bias (the truth plus
        the wander's mean over the windows), channel units: with the correlated wander its mean
        over the windows taken out (``static_wander.run_mean_bias_cov``); with independent
        window errors the fit's bias sigma (that model has no shared wander, its run mean is
        confounded with b), as is ``bias_sigma``. ``None``: not formed.
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
    bias_reference: BiasReference = "run_mean"
    bias_sigma_run_mean: FloatArray | None = None

    @property
    def params(self) -> FloatArray:
        """(12,) parameter vector in the order of :data:`~.static_design.PARAMETER_NAMES`."""
        return np.concatenate([self.bias, self.K.ravel()])

    @property
    def sigma(self) -> FloatArray:
        """(12,) one-sigma uncertainties in the order of :data:`~.static_design.PARAMETER_NAMES`."""
        return np.sqrt(np.diag(self.cov))

    @property
    def bias_sigma(self) -> FloatArray:
        """(3,) one-sigma uncertainty of the bias."""
        return self.sigma[:3]

    @property
    def K_sigma(self) -> FloatArray:
        """(3, 3) one-sigma uncertainty of K."""
        return self.sigma[3:].reshape(3, 3)


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


def _gls(H: FloatArray, y: FloatArray, S: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """Joint GLS: θ (12,), Cov(θ) (12, 12) and Q = Σ rᵀ S⁻¹ r for windows with covariances S (m, 3, 3)."""
    W = np.linalg.inv(S)
    HtW = np.einsum("wai,wab->wib", H, W)
    N = np.einsum("wib,wbj->ij", HtW, H)
    C = np.linalg.inv(N)
    theta = C @ np.einsum("wib,wb->i", HtW, y)
    r = y - np.einsum("wai,i->wa", H, theta)
    return theta, 0.5 * (C + C.T), float(np.einsum("wa,wab,wb->", r, W, r))


def _variance_components(
    X: FloatArray, y: FloatArray, V: FloatArray, K: FloatArray, known: FloatArray | None = None
) -> tuple[FloatArray, FloatArray, float, FloatArray]:
    """Between-window covariance per window: the pose part t M_w (m, 3, 3) and diag(τ²) (3,), inflated.

    The pose variance t (m/s²)² solves the Paule-Mandel equation pooled over the channels,
    each channel refitted with its marginal variances v_w,i + t M_w,ii (Paule & Mandel,
    J. Res. NBS 87 (1982) 377):

        Σ_i min_θi Σ_w r_w,i² / (V_w,ii + t M_w,ii) = 3 (m − 4),

    which always has a solution (M_w,ii > 0 for a channel with any misalignment; the joint
    statistic would not, since pose errors never reach the reading along gravity); then each
    channel's own τ_i² (``own_channel_variance``). A variance estimated with ν degrees of
    freedom makes standardised errors Student-t_ν rather than normal, so each is multiplied
    by ν / (ν − 2), the variance of t_ν (``t_factor``): a plain χ²/dof rescaling with the
    8 dof of one channel would give z ~ t_8 (3σ coverage 98.3 %).

    The own excess is the plain Paule-Mandel estimate (no significance gate) when each
    channel has at least :data:`UNGATED_MIN_DOF` residual degrees of freedom; below that the
    95 % gate of ``own_channel_variance`` holds. Returns the pose part (m, 3, 3), the own
    excess (3,), the pose variance t and the gated own excess (3,), which the slow wander's
    REML keeps as its independent nugget (``static_wander``).

    ``known`` (n, m, 3): effects on the window means of known random inputs, one standard
    uncertainty each, the same draw in every window (``bench.uncertainty.type_a``); their
    expected share of each statistic (``window_noise.known_share``) is taken out before it is
    equated to its degrees of freedom, so t and τ² hold only the scatter they do not explain
    (each clipped at zero).
    """
    m = X.shape[0]
    dof = m - 4
    M = pose_scatter(K, X[:, 1:4])
    md = np.clip(np.diagonal(M, axis1=1, axis2=2), 0.0, None)
    vd = np.diagonal(V, axis1=1, axis2=2)
    kn = np.zeros((0, m, 3)) if known is None else np.asarray(known, dtype=float)
    t = 0.0
    if np.any(md > 0):

        def pooled_q(t: float) -> float:
            return sum(
                pm_statistic(X, y[:, i], vd[:, i] + t * md[:, i])
                - known_share(X, kn[:, :, i].T, vd[:, i] + t * md[:, i])
                for i in range(3)
            )

        t = solve_decreasing(pooled_q, 3 * dof, float(np.median(vd / np.maximum(md, 1e-300))))
    gated = own_channel_variance(X, y, vd + t * md, known=kn)
    own = gated if dof < UNGATED_MIN_DOF else own_channel_variance(X, y, vd + t * md, gated=False, known=kn)
    return t * t_factor(3 * dof) * M, own * t_factor(dof), t, gated * t_factor(dof)


def between_window_excess(
    f_m_s2: FloatArray,
    y_mean: FloatArray,
    y_cov: FloatArray,
    K: FloatArray,
    *,
    known: FloatArray | None = None,
) -> tuple[FloatArray, float, FloatArray]:
    """The between-window covariance :func:`fit_static` adds to each window, for a given K.

    :param f_m_s2: (m, 3) specific forces; :param y_mean: (m, 3) window means;
        :param y_cov: (m, 3, 3) their within-window covariances; :param K: (3, 3) scale matrix.
    :param known: (n, m, 3) known random effects whose expected share is taken out of the
        Paule-Mandel statistics (:func:`_variance_components`), or ``None``.
    :returns: the excess (m, 3, 3) as the fit adds it (pose part + diag(τ²), each inflated by
        ν/(ν − 2)), the pose variance t ((m/s²)²) and the own excess τ² (3,), both before the
        inflation. Zero with 4 windows or fewer.
    """
    f, y, V = _validate(f_m_s2, y_mean, y_cov)
    m = f.shape[0]
    if m <= 4:
        return np.zeros((m, 3, 3)), 0.0, np.zeros(3)
    X = check_design(f)
    V = 0.5 * (V + np.transpose(V, (0, 2, 1)))
    pose, own, t, _ = _variance_components(X, y, V, np.asarray(K, dtype=float), known)
    return pose + own[None, :, None] * np.eye(3)[None], t, own / t_factor(m - 4)


def fit_static(
    f_m_s2: FloatArray,
    y_mean: FloatArray,
    y_cov: FloatArray,
    *,
    between_window: bool = True,
    mid_s: FloatArray | None = None,
) -> StaticFit:
    """Fit bias and full K of a triad to static window means with known specific force.

    :param f_m_s2: (m, 3) specific force in the sensor frame per window (m/s²),
        e.g. Rᵀ [0, 0, g] from the table angles.
    :param y_mean: (m, 3) window means of the raw channels (channel units).
    :param y_cov: (m, 3, 3) covariance of each window mean (``window_noise``).
    :param between_window: estimate the additive between-window variance τ² (default);
        ``False`` trusts the within-window covariances alone.
    :param mid_s: (m,) window times (s). With them, a slow wander correlated between
        windows (per channel, exponential correlation, REML; ``slow_noise``) replaces the
        independent excess when it fits the windows better by
        :data:`~.static_wander.WANDER_GATE` (:func:`~.static_wander.fit_slow_wander`): on a
        long recording the windows share their errors (drift over the day, temperature) and
        independent errors would understate the sigmas.
    :returns: :class:`StaticFit`.
    :raises ValueError: bad shapes or values, fewer than 4 windows, or an orientation set
        that cannot identify all 12 parameters (the message names them).
    """
    f, y, V = _validate(f_m_s2, y_mean, y_cov)
    m = f.shape[0]
    X = check_design(f)
    H = design_rows(f)
    V = 0.5 * (V + np.transpose(V, (0, 2, 1)))
    theta, C, _ = _gls(H, y, V)
    excess = np.zeros((m, 3, 3))
    pose_part, own_part, pose_t, own_gated = np.zeros((m, 3, 3)), np.zeros(3), 0.0, np.zeros(3)
    if between_window and m > 4:
        for _ in range(3):  # the pose-scatter shape depends on K: two refinements suffice
            pose_part, own_part, pose_t, own_gated = _variance_components(X, y, V, theta[3:].reshape(3, 3))
            excess = pose_part + own_part[None, :, None] * np.eye(3)[None]
            theta, C, _ = _gls(H, y, V + excess)
    S = V + excess
    slow = None
    if between_window and mid_s is not None:
        mid = np.asarray(mid_s, dtype=float).reshape(-1)
        if mid.shape != (m,) or not np.all(np.isfinite(mid)):
            raise ValueError(f"window times must be finite (m,) = ({m},), got shape {mid.shape}")
        slow = fit_slow_wander(f, y, V, theta[3:].reshape(3, 3), mid, own_gated, pose_t)
    run_mean_var = None
    if slow is not None:
        wc = window_covariance(V, mid, slow.noise, slow.J, slow.nugget)
        g_fit = gls(H.reshape(3 * m, 12), y.reshape(-1), wc)
        theta, C = g_fit.theta, g_fit.cov
        cov_run = run_mean_bias_cov(H.reshape(3 * m, 12), C, wc.factor().solve, slow.noise, mid)
        run_mean_var = np.clip(np.diag(cov_run), 0.0, None)
        excess = wc.blocks - V + slow.noise.tau2[None, :, None] * np.eye(3)[None]
        S = V + excess
    resid = y - np.einsum("wai,i->wa", H, theta)
    # Cov(r_w) = S_w − H_w C H_wᵀ for the GLS fit with the true S
    r_var = np.diagonal(S - np.einsum("wai,ij,wbj->wab", H, C, H), axis1=1, axis2=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = np.sqrt(np.clip(r_var, 0.0, None))
        norm_resid = np.where(denom > 0, resid / denom, 0.0)
    var_within = np.diagonal(V, axis1=1, axis2=2)
    chi2 = float(np.sum(resid**2 / var_within))
    excess_var = np.diagonal(excess, axis1=1, axis2=2).copy()
    if slow is not None:
        model = (
            "window means: batch-means covariance from each window's samples; between windows: "
            "pose scatter common to the channels (joint fit) + each channel's slow wander, sigma = ["
            + ", ".join(f"{np.sqrt(t):.3g}" for t in slow.noise.tau2)
            + "] channel units, correlated between windows with time constant "
            + f"{slow.noise.corr_time_s:.0f} s "
            f"(REML, 2 delta loglik {slow.lr:.1f} over independent windows)"
        )
    elif between_window:
        model = (
            "window means: batch-means covariance from each window's samples; between windows: "
            "pose scatter common to the channels (joint fit) + each channel's own excess, rms sigma = ["
            + ", ".join(f"{np.sqrt(t):.3g}" for t in excess_var.mean(axis=0))
            + "] channel units"
        )
    else:
        model = "window means: batch-means covariance from each window's samples"
    return StaticFit(
        bias=theta[:3].copy(),
        K=theta[3:].reshape(3, 3).copy(),
        cov=C,
        residuals=resid,
        normalized_residuals=norm_resid,
        chi2=chi2,
        dof=3 * (m - 4),
        excess_var=excess_var,
        noise_model=model,
        bias_reference="long_run" if slow is not None else "run_mean",
        bias_sigma_run_mean=np.sqrt(np.diag(C)[:3] if run_mean_var is None else run_mean_var),
    )
