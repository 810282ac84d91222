"""A planned design's predicted uncertainties and table time (:func:`evaluate`).

The window fit's prediction is the least-squares covariance of the static window means with the
unit's coloured noise (``bench.planning.information``, ``bench.planning.noise``); the
every-sample fit's is that of every sample of the design's trajectory, moves and settling
included (``bench.planning.every_sample``). Each is stated beside the white-noise bound of any
motion for the same table time. :class:`Targets` are the expanded uncertainties a plan must meet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from bench.planning.every_sample import every_sample_uncertainty
from bench.planning.information import (
    PredictedUncertainty,
    predicted_uncertainty,
    tilt_response,
    white_bound_bias,
    white_bound_k,
)
from bench.planning.noise import UnitNoise, window_mean_covariance
from bench.planning.sampled import SampledTrajectory
from bench.procedures.preview import DEFAULT_TABLE_LIMITS, TableLimits, preview
from bench.procedures.steps import Dwell, Procedure
from bench.records import WindowKind

Fit = Literal["window", "every-sample"]
"""``"window"``: the static window fit of the dwells; ``"every-sample"``: the dynamic batch fit
of every sample, moves and settling included (``bench.planning.every_sample``)."""

EVERY_SAMPLE_FS_HZ = 20.0
"""Sample rate of the trajectory the every-sample prediction is computed on (Hz); the white
part scales as N²·f_s·Σxxᵀ ≈ N²∫xxᵀdt, so the prediction does not depend on it."""

WINDOW_TILT_NOTE = (
    "the prediction carries a base tilt, which these poses separate from bias and K, but the window fit "
    "does not estimate it: on a tilted base the achieved K error exceeds the prediction (a 3 arcmin tilt "
    "leaks about 870 urad into K); the every-sample fit (planned-tumble) estimates it"
)
"""Said of every window-fit prediction with the tilt (docs/planning.md)."""


@dataclass(frozen=True)
class Targets:
    """Wanted expanded uncertainties (k = 2); ``None``: no target for that group.

    :param bias_m_s2: largest bias U (m/s²).
    :param scale: largest scale-factor U (dimensionless).
    :param misalignment_rad: largest off-diagonal U (rad).
    """

    bias_m_s2: float | None = None
    scale: float | None = None
    misalignment_rad: float | None = None

    def __post_init__(self) -> None:
        for name in ("bias_m_s2", "scale", "misalignment_rad"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ValueError(f"target {name}: expected a number > 0, got {v!r}")
        if self.bias_m_s2 is None and self.scale is None and self.misalignment_rad is None:
            raise ValueError("targets: give at least one of bias, scale, misalignment")

    def met_by(self, u: PredictedUncertainty) -> bool:
        """Every target is met at k = 2 by the predicted standard uncertainties."""
        pairs = ((self.bias_m_s2, u.bias), (self.scale, u.scale), (self.misalignment_rad, u.misalignment))
        return all(t is None or 2.0 * s <= t for t, s in pairs)


@dataclass(frozen=True)
class Evaluation:
    """A procedure's prediction: table time and the window fit's standard uncertainties.

    :param procedure: the procedure evaluated.
    :param duration_s: total table time, moves and settling included (s).
    :param predicted: the fit's predicted σ (k = 1).
    :param bound_k: white-noise bound σ(K_ij) of any motion for ``duration_s``.
    :param bound_bias_m_s2: white-noise bound σ(b_i) for ``duration_s`` (m/s²).
    :param fit: the fit the prediction is for (:data:`Fit`).
    :param notes: what the prediction leaves out or cannot tell apart, one sentence each
        (a nuisance parameter the design cannot separate, a tilt the fit does not estimate).
    """

    procedure: Procedure
    duration_s: float
    predicted: PredictedUncertainty
    bound_k: float
    bound_bias_m_s2: float
    fit: Fit = "window"
    notes: tuple[str, ...] = ()

    @property
    def k_fraction_of_bound(self) -> float:
        """Predicted RMS σ(K_ij) over the bound: 1 is the best any motion can do."""
        return self.predicted.k_rms / self.bound_k


def rotation_deg(angles_deg: tuple[float, ...]) -> np.ndarray:
    """R = Rz(outer)·Rx(middle)·Rz(inner) of the default geometry (base from sensor)."""

    def rz(a: float) -> np.ndarray:
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def rx(a: float) -> np.ndarray:
        c, s = math.cos(a), math.sin(a)
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])

    o, m, i = (math.radians(a) for a in angles_deg)
    R: np.ndarray = rz(o) @ rx(m) @ rz(i)
    return R


def evaluate(
    proc: Procedure,
    noise: UnitNoise,
    *,
    limits: TableLimits = DEFAULT_TABLE_LIMITS,
    g_m_s2: float = 9.80665,
    with_tilt: bool = True,
    fit: Fit = "window",
    sampled: SampledTrajectory | None = None,
) -> Evaluation:
    """Predict a static procedure's uncertainties under ``fit`` and its table time.

    ``"every-sample"`` samples the procedure's specific-force trajectory on ``limits``
    (``bench.planning.trajectory``) and predicts the every-sample fit's covariance on it; when
    ``sampled`` (sampled on the same ``limits``) begins with the procedure's steps, its first
    samples are taken instead (``bench.planning.sampled``: the same samples).

    :raises ValueError: the procedure has no static windows with a fixed dwell, exceeds the
        table's limits, or does not identify the parameters.
    """
    pv = preview(proc, limits)
    if pv.problems:
        raise ValueError(f"{proc.name}: {pv.problems[0]}")
    if any(isinstance(s, Dwell) and s.duration_s is None for s in proc.steps):
        raise ValueError(f"{proc.name}: the dwell must be fixed to predict the fit")
    wins = [w for w in pv.windows if w.kind == WindowKind.STATIC]
    if len(wins) < 4:
        raise ValueError(f"{proc.name}: {len(wins)} static windows, the window fit needs at least 4")
    T = pv.duration_s
    bounds = white_bound_k(noise.white_m_s2_rt_hz, T, g_m_s2), white_bound_bias(noise.white_m_s2_rt_hz, T)
    if fit == "every-sample":
        same = sampled is not None and (sampled.fs_hz, sampled.g_m_s2) == (EVERY_SAMPLE_FS_HZ, g_m_s2)
        if sampled is not None and same and sampled.begins(proc):
            traj = sampled.prefix(proc)
        else:
            traj = SampledTrajectory.sample(proc, EVERY_SAMPLE_FS_HZ, limits, g_m_s2)
        t, f, resp = traj.t_s, traj.f_m_s2, traj.nuisance
        notes: list[str] = []
        cols = [0, 1, 2, 3, 4] if with_tilt else [0, 1, 2]
        try:
            ue = every_sample_uncertainty(t, f, noise, nuisance=resp[:, :, cols])
        except ValueError:
            notes.append(
                "the design's motion does not separate the lever arm"
                + (" and the base tilt" if with_tilt else "")
                + " from bias and K: the prediction leaves them out, and a lever arm or tilt present goes "
                "into bias and K"
            )
            ue = every_sample_uncertainty(t, f, noise)
        return Evaluation(proc, T, ue, *bounds, fit, tuple(notes))
    starts = np.array([w.start_s for w in wins])
    durations = np.array([w.duration_s for w in wins])
    Rt = np.stack([rotation_deg(w.pose_deg).T for w in wins])
    f = Rt @ np.array([0.0, 0.0, g_m_s2])
    C = window_mean_covariance(noise, starts, durations)
    if not with_tilt:
        return Evaluation(proc, T, predicted_uncertainty(f, C), *bounds)
    try:
        u = predicted_uncertainty(f, C, tilt_response(Rt, g_m_s2))
    except ValueError:
        return Evaluation(
            proc,
            T,
            predicted_uncertainty(f, C),
            *bounds,
            notes=(
                "these poses cannot separate a base tilt from the bias and K: the prediction is for a "
                "level base; a tilt of d rad goes into them (about g*d in the bias)",
            ),
        )
    return Evaluation(proc, T, u, *bounds, notes=(WINDOW_TILT_NOTE,))
