"""REML estimate of the window-mean noise model of ``slow_noise``.

The noise parameters θ_n = (τ², T_c, σ_p², ε²) of the covariance C(θ_n) of ``slow_noise`` are
those that maximise the restricted log-likelihood of the stacked window means for a design X
(Harville, JASA 72 (1977) 320, eq. 4.3):

    −2 ℓ_REML(θ_n) = χ² + ln|C| + ln|Xᵀ C⁻¹ X| + (n − p) ln 2π,

searched on a log scale of each variance (relative to the windows' own noise), for each
correlation time T_c of a grid (or over log T_c as well), with the GLS fit under the winner.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from bench.estimation.slow_noise import FloatArray, GlsFit, NoiseParams, gls, window_covariance
from bench.estimation.warm_search import memoised, warm_minimum
from bench.estimation.window_covariance import FixedQuadratic, fixed_quadratic, invert_blocks

CORRELATION_TIMES_FRACTION = (0.0, 0.3, 1.0, 3.0)
"""Grid of T_c tried, as fractions of the span of the window times (0 = white between windows)."""
_LOG_FLOOR = -30.0


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

    def neg_reml(v: FloatArray) -> float:
        """−ℓ_REML at v = (u, T_c)."""
        try:
            wc = window_covariance(V, mid_s, unpack(v[:-1], float(v[-1])), J_pose, fixed)
            if inv is not None:
                wc = replace(wc, blocks_inverse=inv, blocks_logdet=logdet_b)
            return -gls(X, z, wc, fixed_xz=fixed_xz).loglik_reml
        except ValueError:
            return 1e300

    known = memoised(neg_reml)  # the searches below come back to points already evaluated

    def objective(u: FloatArray, tc: float) -> float:
        return known(np.append(np.asarray(u, dtype=float), tc))

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
