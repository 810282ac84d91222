"""Monte Carlo of the static budget (JCGM 101 style): simulated runs with every Type B input drawn
from its distribution, refitted, each with the budget a certificate would state.

Sample-level simulation (``tests/support/static_sim.py``, scipy rotations); the fit is told the
nominal specific force, table angles, g and temperatures, as a bench would. Used by
``tests/bench/uncertainty/test_uncertainty_budget.py`` and ``benchmarks/study_budget_type_b.py``.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from bench.estimation.static_fit import fit_static
from bench.estimation.window_noise import pooled_mean_covariances, window_noise
from bench.uncertainty.budget import TypeBInput, uncertainty_budget
from bench.uncertainty.inputs import daq_inputs, gravity_input, table_inputs, temperature_inputs
from bench.uncertainty.type_a import type_a_without_type_b
from tests.support.static_sim import G_LOCAL, TUMBLE_12_DEG, simulate_run, tumble_specific_force

AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # middle (x) then inner (z): R = Rx(a) Rz(b)
Q_RAD = np.deg2rad(TUMBLE_12_DEG)
TEMP_C = np.linspace(24.0, 24.6, 12) + 0.05 * np.sin(np.arange(12))

U_MC = {
    "angle": np.deg2rad(0.002),
    "tilt": 1e-5,
    "g_u": 2e-3,
    "gain": 1e-4,
    "offset": 1e-5,
    "cb": 3e-4,
    "ck": 2e-5,
}
"""Type B standard uncertainties: large enough to be seen next to the noise, mostly in inputs
whose effect the fit's model absorbs (no trace in the residuals)."""
U_MC_UNMODELLED = {**U_MC, "angle": np.deg2rad(0.005), "tilt": 1e-4, "cb": 3e-3, "ck": 2e-4}
"""A base tilt and temperature coefficients large enough to leave window-to-window residuals
comparable to the window noise."""
POSE_ERROR_RAD = np.deg2rad(3.0 / 60.0)
"""Each pose placed 3 arc-minutes off (1σ per rotation angle): a real between-window excess,
larger than the window noise across gravity."""
CASES = {"absorbed": U_MC, "unmodelled": U_MC_UNMODELLED}


def budget_inputs(u_mc: dict[str, float], b: np.ndarray, K: np.ndarray) -> list[TypeBInput]:
    """The Type B inputs of the simulated bench at the fitted b (3,) and K (3, 3)."""
    f = tumble_specific_force()
    return [
        *table_inputs(AXES, Q_RAD, np.eye(3), G_LOCAL, angle_u_rad=u_mc["angle"], tilt_u_rad=u_mc["tilt"]),
        gravity_input(f, G_LOCAL, u_mc["g_u"]),
        *daq_inputs(b + f @ K.T, u_mc["gain"], u_mc["offset"], "V"),
        *temperature_inputs(TEMP_C, f, K, u_mc["cb"], u_mc["ck"]),
    ]


@dataclass(frozen=True)
class Draw:
    """One simulated run: the fit's error θ̂ − θ (12,) and the u_c (12,) of its budget formed
    three ways: ``before`` (Type A the fit's σ, sensitivities weighted by the within-window
    covariances), ``after`` (Type A with the inputs' share removed, sensitivities with the fit's
    own weights), ``type_a`` (the Type A line after), ``clipped`` (excess components estimated below zero) and
    ``clean_sigma`` (12,): the fit's σ on the same run (same truth, same noise) without any Type B
    input, what the Type A line should be when each input is counted once; ``k_after`` (12,) the
    coverage factors of the budget after (t_95.45 %(ν_eff))."""

    error: np.ndarray
    before: np.ndarray
    after: np.ndarray
    type_a: np.ndarray
    fit_sigma: np.ndarray
    clean_sigma: np.ndarray
    clipped: int
    k_after: np.ndarray


def draw(
    rng: np.random.Generator, u_mc: dict[str, float], *, paired: bool = True, pose_error_rad: float = 0.0
) -> Draw:
    """Simulate, fit and budget one run with its Type B inputs drawn from their normal distributions
    (``paired``: also fit the same run without them; ``clean_sigma`` is NaN otherwise;
    ``pose_error_rad``: each pose placed off by that angle, 1σ per rotation angle)."""
    d_angle = rng.normal(0, u_mc["angle"], 2)
    tilt = rng.normal(0, u_mc["tilt"], 2)
    g_true = G_LOCAL + rng.normal(0, u_mc["g_u"])
    R_true = Rotation.from_rotvec([*tilt, 0.0]) * Rotation.from_euler(
        "XZ", TUMBLE_12_DEG + np.rad2deg(d_angle), degrees=True
    )
    f_true = R_true.inv().apply([0.0, 0.0, g_true])
    twin = copy.deepcopy(rng)  # the noise does not depend on f: the same run without Type B inputs
    run = simulate_run(rng, f=f_true, dwell_s=10.0, fs=100.0, pose_error_rad=pose_error_rad)
    cb, ck = rng.normal(0, u_mc["cb"], 3), rng.normal(0, u_mc["ck"], 3)
    gain, offset = rng.normal(0, u_mc["gain"], 3), rng.normal(0, u_mc["offset"], 3)
    dT = TEMP_C - TEMP_C.mean()
    noises = []
    for w, x in enumerate(run.windows):
        out = run.K_true @ f_true[w]
        x = x + dT[w] * (np.diag(run.K_true) * cb + out * ck)
        noises.append(window_noise((1 + gain) * x + offset))
    f = tumble_specific_force()
    y, V = np.array([n.mean for n in noises]), pooled_mean_covariances(noises)
    fit = fit_static(f, y, V)
    clean_sigma = np.full(12, np.nan)
    if paired:
        clean = simulate_run(twin, f=f, dwell_s=10.0, fs=100.0, pose_error_rad=pose_error_rad)
        cn = [window_noise(x) for x in clean.windows]
        clean_sigma = fit_static(f, np.array([n.mean for n in cn]), pooled_mean_covariances(cn)).sigma
    truth = np.concatenate([run.bias_true, run.K_true.ravel()])
    inputs = budget_inputs(u_mc, fit.bias, fit.K)
    before = uncertainty_budget(f, fit.bias, fit.K, fit.cov, inputs, window_cov=V).u_c
    ta = type_a_without_type_b(f, y, V, fit.K, inputs)
    cov_a = np.diag((fit.sigma * ta.ratio()) ** 2)
    after_budget = uncertainty_budget(
        f, fit.bias, fit.K, cov_a, inputs, window_cov=ta.weights_cov, type_a_dof=ta.dof
    )
    after = after_budget.u_c
    return Draw(
        fit.params - truth,
        before,
        after,
        np.sqrt(np.diag(cov_a)),
        fit.sigma,
        clean_sigma,
        len(ta.below_zero),
        np.array([q.k for q in after_budget.quantities]),
    )


@dataclass(frozen=True)
class MonteCarlo:
    """Over n runs, per parameter (12,): the standard deviation of the errors, their mean, the
    RMS over the runs of each budget's u_c (what the certificates state on average) and the RMS
    of each run's error over its own u_c (z, before and after), and the fraction of runs whose
    error lies within U (2 u_c before, k u_c after; 95.45 % when U is honest)."""

    n: int
    spread: np.ndarray
    mean_error: np.ndarray
    u_before: np.ndarray
    u_after: np.ndarray
    u_type_a: np.ndarray
    u_fit: np.ndarray
    u_clean: np.ndarray
    z_before: np.ndarray
    z_after: np.ndarray
    clipped_runs: int
    cover_before: np.ndarray
    cover_after: np.ndarray


def monte_carlo(
    u_mc: dict[str, float], seed: int, n: int, *, paired: bool = True, pose_error_rad: float = 0.0
) -> MonteCarlo:
    """``n`` runs of :func:`draw` from ``numpy.random.default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    draws = [draw(rng, u_mc, paired=paired, pose_error_rad=pose_error_rad) for _ in range(n)]
    err = np.array([d.error for d in draws])

    def rms(a: list[np.ndarray]) -> np.ndarray:
        return np.sqrt(np.mean(np.square(a), axis=0))

    return MonteCarlo(
        n=n,
        spread=err.std(axis=0, ddof=1),
        mean_error=err.mean(axis=0),
        u_before=rms([d.before for d in draws]),
        u_after=rms([d.after for d in draws]),
        u_type_a=rms([d.type_a for d in draws]),
        u_fit=rms([d.fit_sigma for d in draws]),
        u_clean=rms([d.clean_sigma for d in draws]),
        z_before=rms([d.error / d.before for d in draws]),
        z_after=rms([d.error / d.after for d in draws]),
        clipped_runs=sum(d.clipped > 0 for d in draws),
        cover_before=np.mean([np.abs(d.error) <= 2 * d.before for d in draws], axis=0),
        cover_after=np.mean([np.abs(d.error) <= d.k_after * d.after for d in draws], axis=0),
    )


def sd_sampling_error(n: int) -> float:
    """Relative standard error of a standard deviation from n normal draws, 1/√(2(n − 1))."""
    return 1.0 / math.sqrt(2.0 * (n - 1))
