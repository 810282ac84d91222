"""The unit's bias wander averaged over one run: the line that makes a bias U the long-run bias's.

The bias a certificate carries is the unit's long-run bias; one run sees it plus the average
over the run of its slow wander, which a run shorter than a few correlation times cannot
measure itself (a static fit with independent window errors not at all: a shift common to the
windows is b). Given the unit's wander (Gauss–Markov, level σ_w m/s² per sensor axis,
correlation time T_c; settings ``bias_wander_m_s2``, ``bias_wander_corr_time_s``), the bias
gets its own line per sensor axis j, with u = σ_w and

    ∂b_i/∂X_j = K_ij · r(T),   r(T)² = 2 (T_c/T) [1 − (T_c/T)(1 − e^(−T/T_c))],

r(T)² σ_w² the variance of the time average over T of a stationary process with autocovariance
σ_w² e^(−|τ|/T_c) (Papoulis & Pillai, *Probability, Random Variables and Stochastic
Processes*, 4th ed., §9-5, the variance of a time average), T the fitted span (a moving fit:
the recording; a static fit: first window's start to last window's end). The bias's Type A
line is then the fit's sigma against the run's mean bias (``DynamicFit.bias_sigma_run_mean``,
``StaticFit.bias_sigma_run_mean``), so a wander the fit itself estimated is not counted twice
(:func:`with_wander`). Used by the moving budget (``bench.uncertainty.dynamic``) and the
certificate's static budget (``station.certificates.budget``).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from bench.uncertainty.budget import WANDER_GROUP, TypeBInput

FloatArray = npt.NDArray[np.float64]

_LETTERS = ("x", "y", "z")


def run_mean_factor(span_s: float, corr_time_s: float) -> float:
    """r(T) of the module docstring: the standard deviation of a unit-level Gauss–Markov
    process's average over ``span_s`` (s) about its long-run mean; ``corr_time_s`` T_c (s)."""
    if not (span_s > 0 and corr_time_s > 0):
        raise ValueError(f"span_s and corr_time_s must be > 0, got {span_s!r}, {corr_time_s!r}")
    x = corr_time_s / span_s
    return math.sqrt(2.0 * x * (1.0 - x * -math.expm1(-1.0 / x)))


def wander_inputs(
    span_s: float, K: FloatArray, wander: tuple[float, float]
) -> tuple[list[TypeBInput], FloatArray]:
    """The bias's wander lines (module docstring): three inputs (one per sensor axis) and their
    sensitivities (3, 12) (bias rows only). ``wander`` = (σ_w m/s², T_c s) of the unit."""
    level, tc = wander
    if not (math.isfinite(level) and level >= 0):
        raise ValueError(f"bias wander level must be finite and >= 0 m/s2, got {level!r}")
    r = run_mean_factor(span_s, tc)
    Km = np.asarray(K, dtype=float).reshape(3, 3)
    basis = (
        f"unit's bias wander (Gauss-Markov, level {level:.3g} m/s2, correlation time {tc:g} s): "
        f"its average over the {span_s:.0f} s run about the long-run bias, r = {r:.3g}"
    )
    inputs = [
        TypeBInput(f"bias wander over the run, sensor axis {letter}", level, "m/s2", group=WANDER_GROUP,
                   channel=j, basis=basis)
        for j, letter in enumerate(_LETTERS)
    ]  # fmt: skip
    sens = np.zeros((3, 12))
    sens[:, :3] = Km.T * r  # row j: ∂b_i/∂X_j = K_ij r
    return inputs, sens


def with_wander(
    cov_type_a: FloatArray,
    bias_sigma_run_mean: FloatArray,
    span_s: float,
    K: FloatArray,
    wander: tuple[float, float],
) -> tuple[FloatArray, list[TypeBInput], FloatArray]:
    """The Type A covariance with the bias against the run's mean, and the wander's lines.

    :param cov_type_a: (12, 12) the fit's Type A covariance ([b, vec K]).
    :param bias_sigma_run_mean: (3,) the bias sigma against the run's mean (channel units): the
        bias rows and columns of ``cov_type_a`` are replaced by its squares on the diagonal.
    :param span_s: T (s); :param K: (3, 3); :param wander: (σ_w m/s², T_c s).
    :returns: (12, 12) covariance, the three inputs and their sensitivities (3, 12).
    """
    s = np.asarray(bias_sigma_run_mean, dtype=float).reshape(3)
    if not np.all(np.isfinite(s)) or np.any(s < 0):
        raise ValueError(f"the bias sigma against the run's mean must be finite and >= 0, got {s!r}")
    C = np.array(cov_type_a, dtype=float, copy=True)
    C[:3, :] = 0.0
    C[:, :3] = 0.0
    C[:3, :3] = np.diag(s**2)
    inputs, sens = wander_inputs(span_s, K, wander)
    return C, inputs, sens
