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
parameters the difference is large).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
from scipy.linalg import cho_factor, cho_solve
from scipy.linalg.lapack import dpotrf, dpotrs
from scipy.optimize import minimize, minimize_scalar

from bench.estimation.warm_search import warm_minimum
from bench.estimation.window_covariance import (
    FixedQuadratic,
    WindowCovariance,
    fixed_quadratic,
    invert_blocks,
)

FloatArray = npt.NDArray[np.float64]

CORRELATION_TIMES_FRACTION = (0.0, 0.3, 1.0, 3.0)
"""Grid of T_c tried, as fractions of the span of the window times (0 = white between windows)."""
_LOG_FLOOR = -30.0


@dataclass(frozen=True)
class NoiseParams:
    """Noise parameters beyond the windows' own scatter.

    :param tau2: (3,) slow-noise variance per channel (channel units²).
    :param corr_time_s: its correlation time T_c (s); 0 = independent between windows.
    :param pose_var_rad2: random pose-error variance per angle (rad²); 0 = none.
    :param excess_var: (3,) ε_i², each channel's own excess from window to window (channel
        units²), or ``None`` (none).
    :param excess_channels: the channels whose ε_i² is a free parameter (``fit_noise``
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


def _powell(
    fun: Callable[[FloatArray], float], u0: FloatArray, bounds: list[tuple[float, float]]
) -> tuple[float, FloatArray]:
    """Bounded Powell minimum of ``fun`` from ``u0``, each line searched over its whole segment.

    For starts that are not a nearby model's estimate: a search of each line near its start
    (``warm_search``) can stay on a flat floor of a variance or stop short in the long valley
    of (log τ², log T_c). scipy's bounded Powell fails (an empty reduction in its
    extrapolation step) when an iteration leaves the point where it was; the search is then
    finished by Brent (one parameter) or Nelder-Mead (more), and the better of that and the
    start is kept.
    """
    try:
        res = minimize(fun, u0, method="Powell", bounds=bounds, options={"xtol": 1e-3, "ftol": 1e-6})
        return float(res.fun), np.asarray(res.x, dtype=float)
    except ValueError:
        pass
    if u0.size == 1:
        lo, hi = bounds[0]
        r = minimize_scalar(
            lambda a: fun(np.array([a])), bounds=(lo, hi), method="bounded", options={"xatol": 1e-3}
        )
        val, x = float(r.fun), np.array([float(r.x)])
    else:
        r = minimize(fun, u0, method="Nelder-Mead", bounds=bounds, options={"xatol": 1e-3, "fatol": 1e-6})
        val, x = float(r.fun), np.asarray(r.x, dtype=float)
    f0 = fun(u0)
    return (val, x) if val <= f0 else (f0, np.asarray(u0, dtype=float))


def fit_noise(
    X: FloatArray,
    z: FloatArray,
    V: FloatArray,
    mid_s: FloatArray,
    *,
    J_pose: FloatArray | None = None,
    fixed: FloatArray | None = None,
    estimate_pose: bool = False,
    init: NoiseParams | None = None,
    channel_gain: FloatArray | None = None,
    tau2_cap: Callable[[float], FloatArray | None] | None = None,
    corr_times_s: Sequence[float] | None = None,
    refine_corr_time: bool = False,
    near_init: bool = False,
    excess_start: FloatArray | None = None,
) -> tuple[NoiseParams, GlsFit]:
    """REML estimate of the noise parameters for design X; returns them and the GLS fit under them.

    τ² (and σ_p² when ``estimate_pose``) are optimised on a log scale (Powell's directions with
    line searches bracketed from the start, ``warm_search``) for each
    T_c of ``CORRELATION_TIMES_FRACTION`` × span; the best ℓ_REML wins. ``init`` (a nearby
    model's estimate) gives the starting point; without it two starts are tried.
    ``tau2_cap`` (T_c -> (3,) upper bound of τ² per channel, or ``None``) bounds the slow
    noise by what the windows' own samples allow (``wander_cap``). ``corr_times_s`` replaces
    the grid of T_c (s; 0 = independent between windows). With ``refine_corr_time`` the grid
    only screens (one common log-scale of τ² per T_c, a 1-D search) and one Powell search
    over (log τ², log T_c) starts from the best screened point (scipy's, each line searched
    whole: :func:`_powell`) (the cap at the shortest T_c
    tried, the tightest, bounds τ² there). With ``near_init`` (``init`` is the estimate of a
    model a column away, as in a selection) the searches at each T_c of the grid are local:
    each line bracketed from the start (``warm_search``); otherwise scipy's bounded Powell
    searches each line whole (:func:`_powell`). Each channel's own excess ε_i² is re-estimated
    on the channels ``excess_start`` (3,) names (> 0 there; its value is the start), or else on
    ``init.excess_channels`` from ``init``'s values; none elsewhere.
    """
    scale = float(np.median(np.diagonal(V, axis1=1, axis2=2)))
    span = float(np.ptp(mid_s)) if mid_s.shape[0] > 1 else 0.0
    g_scale = 1.0
    if estimate_pose:
        if J_pose is None:
            raise ValueError("estimate_pose needs J_pose")
        jn = float(np.median(np.sum(J_pose**2, axis=(1, 2))) / 2.0)
        g_scale = scale / jn if jn > 0 else 1.0
    n_tau = 3 if channel_gain is None else 1
    shape = np.ones(3) if channel_gain is None else channel_gain**2 / np.mean(channel_gain**2)
    if excess_start is not None:
        chans = tuple(int(i) for i in np.flatnonzero(np.asarray(excess_start) > 0))
        e_start = np.asarray(excess_start, dtype=float)[list(chans)]
    elif init is not None and init.excess_channels:
        chans = init.excess_channels
        e_start = np.zeros(len(chans)) if init.excess_var is None else init.excess_var[list(chans)]
    else:
        chans, e_start = (), np.zeros(0)
    n_ex = len(chans)
    # log ε² relative to the window noise; an excess at zero starts where a cold search does
    u_ex = np.where(e_start > 0, np.log(np.maximum(e_start, 1e-300) / scale), -2.0)
    u_ex = np.clip(u_ex, _LOG_FLOOR, 12.0)
    n_base = n_tau + (1 if estimate_pose else 0)
    n_par = n_base + n_ex

    def unpack(u: FloatArray, tc: float) -> NoiseParams:
        tau2 = scale * np.exp(u[:n_tau]) * shape
        tau2 = np.where(u[:n_tau] <= _LOG_FLOOR + 1e-6, 0.0, tau2)
        pv = 0.0
        if estimate_pose:
            pv = 0.0 if u[n_tau] <= _LOG_FLOOR + 1e-6 else g_scale * float(np.exp(u[n_tau]))
        if not chans:
            return NoiseParams(tau2=tau2, corr_time_s=tc, pose_var_rad2=pv, n_tau=n_tau)
        ex = np.zeros(3)
        for k, c in enumerate(chans):
            a = float(u[n_base + k])
            ex[c] = 0.0 if a <= _LOG_FLOOR + 1e-6 else scale * float(np.exp(a))
        return NoiseParams(
            tau2=tau2, corr_time_s=tc, pose_var_rad2=pv, n_tau=n_tau, excess_var=ex, excess_channels=chans
        )

    inv: FloatArray | None = None
    logdet_b: float | None = None
    fixed_xz: FixedQuadratic | None = None
    if not estimate_pose and not chans:  # the windows' own blocks do not change: invert them once
        try:
            wc0 = window_covariance(V, mid_s, NoiseParams(tau2=np.zeros(3)), J_pose, fixed)
            inv, logdet_b = invert_blocks(wc0.blocks)
            xz = np.column_stack([X, z])
            binv_xz = np.matmul(inv, xz.reshape(inv.shape[0], 3, -1)).reshape(z.size, -1)
            fixed_xz = fixed_quadratic(xz, binv_xz, mid_s)
        except ValueError:
            inv, logdet_b, fixed_xz = None, None, None

    def objective(u: FloatArray, tc: float) -> float:
        try:
            wc = window_covariance(V, mid_s, unpack(u, tc), J_pose, fixed)
            if inv is not None:
                wc = replace(wc, blocks_inverse=inv, blocks_logdet=logdet_b)
            return -gls(X, z, wc, fixed_xz=fixed_xz).loglik_reml
        except ValueError:
            return 1e300

    best: tuple[float, NoiseParams] | None = None
    if corr_times_s is None:
        fracs = tuple(f for f in CORRELATION_TIMES_FRACTION if f > 0) if span > 0 else (0.0,)
        corr_times_s = [frac * span for frac in fracs]
    for tc in corr_times_s:
        if init is None:
            starts = [np.full(n_base, -2.0), np.full(n_base, _LOG_FLOOR)]
            starts = [np.append(u, u_ex) for u in starts]
        else:
            t_init = init.tau2 / shape if n_tau == 3 else np.array([np.mean(init.tau2 / shape)])
            u_init = np.log(np.maximum(t_init, scale * np.exp(_LOG_FLOOR)) / scale)
            if near_init:  # a local search from a level at zero would stay on the flat floor:
                u_init = np.where(t_init > 0, u_init, -2.0)  # start where the cold search does
            if estimate_pose:
                pv = init.pose_var_rad2 if init.pose_var_rad2 > 0 else g_scale * np.exp(-2.0)
                u_init = np.append(u_init, np.log(pv / g_scale))
            starts = [np.append(np.clip(u_init, _LOG_FLOOR, 12.0), u_ex)]
        upper = np.full(n_par, 12.0)
        cap = tau2_cap(tc) if tau2_cap is not None else None
        if cap is not None:
            u_cap = np.log(np.maximum(cap, 1e-300) / (scale * shape))
            upper[:n_tau] = np.clip(u_cap if n_tau == 3 else np.min(u_cap), _LOG_FLOOR + 1e-3, 12.0)
        for u0 in starts:
            u0 = np.minimum(u0, upper)
            if refine_corr_time and len(corr_times_s) > 1:
                # screening: only a common log-scale shift of the start at this T_c
                def shifted(a: float, u0: FloatArray = u0, tc: float = tc, up: FloatArray = upper) -> float:
                    return objective(np.clip(u0 + a, _LOG_FLOOR, up), tc)

                r1 = minimize_scalar(shifted, bounds=(-12.0, 12.0), method="bounded", options={"xatol": 0.05})
                val, x = float(r1.fun), np.clip(u0 + float(r1.x), _LOG_FLOOR, upper)
            else:

                def at_tc(u: FloatArray, tc: float = tc) -> float:
                    return objective(u, tc)

                search = warm_minimum if near_init and init is not None else _powell
                val, x = search(
                    at_tc,
                    u0,
                    list(zip([_LOG_FLOOR] * n_par, upper.tolist(), strict=True)),
                )
            if best is None or val < best[0]:
                best = (val, unpack(x, tc))
    assert best is not None
    noise = best[1]
    if refine_corr_time and noise.corr_time_s > 0 and len(corr_times_s) > 1:
        # the grid only screened (one common scale per T_c): the full search over
        # (log τ², log T_c) starts from the best screened point
        tcs = sorted(t for t in corr_times_s if t > 0)
        lo, hi = math.log(tcs[0] / 2.0), math.log(tcs[-1] * 2.0)
        t_best = noise.tau2 / shape if n_tau == 3 else np.array([np.mean(noise.tau2 / shape)])
        u0 = np.log(np.maximum(t_best, scale * np.exp(_LOG_FLOOR)) / scale)
        if estimate_pose:
            u0 = np.append(u0, np.log(max(noise.pose_var_rad2, g_scale * np.exp(_LOG_FLOOR)) / g_scale))
        if chans:
            assert noise.excess_var is not None
            ex_best = noise.excess_var[list(chans)]
            u0 = np.append(u0, np.log(np.maximum(ex_best, scale * np.exp(_LOG_FLOOR)) / scale))
        u0 = np.append(np.clip(u0, _LOG_FLOOR, 12.0), math.log(noise.corr_time_s))
        cap_lo = tau2_cap(tcs[0] / 2.0) if tau2_cap is not None else None
        up = np.full(n_par, 12.0)
        if cap_lo is not None:  # the cap grows with T_c: the smallest T_c's is the tightest
            u_cap = np.log(np.maximum(cap_lo, 1e-300) / (scale * shape))
            up[:n_tau] = np.clip(u_cap if n_tau == 3 else np.min(u_cap), _LOG_FLOOR + 1e-3, 12.0)

        def objective_tc(v: FloatArray) -> float:
            return objective(v[:-1], float(np.exp(v[-1])))

        val, x = _powell(
            objective_tc,
            np.minimum(u0, np.append(up, hi)),
            [*zip([_LOG_FLOOR] * n_par, up.tolist(), strict=True), (lo, hi)],
        )
        if val <= best[0]:
            noise = unpack(x[:-1], float(np.exp(x[-1])))
    return noise, gls(X, z, window_covariance(V, mid_s, noise, J_pose, fixed))


def without_pose(noise: NoiseParams) -> NoiseParams:
    """The same noise with the random pose error removed."""
    return replace(noise, pose_var_rad2=0.0)


def without_excess(noise: NoiseParams) -> NoiseParams:
    """The same noise without the channels' own excess (none, and none to estimate)."""
    return replace(noise, excess_var=None, excess_channels=())
