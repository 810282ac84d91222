"""JSON series of one run for the dashboard: |g| check, residuals, Allan curve.

Every function takes the run's recording (and its fit) and returns plain JSON-able dicts;
the browser draws them. Units travel with the numbers (``*_m_s2``, ``channel_unit``).

* :func:`g_check_series`: per static window the corrected |f̂_w| = |K⁻¹(ȳ_w − b)| against
  ``g_local_m_s2`` (after), and the same with a reference model (before): the nominal scale
  where the channel unit has one (``m/s2``, ``g``) or one is given, else the unit's previous
  calibration. The tumble-test paper's table reports exactly these two columns.
* :func:`residual_series`: per window and channel the fit residual ȳ_w − (b + K f_w) in
  channel units and normalised by the window mean's standard deviation (a z-score: ~N(0, 1)
  when the first-order model explains the window).
* :func:`allan_series`: overlapping Allan deviation (NIST SP1065 eqn (11),
  :func:`bench.estimation.allan.overlapping_allan`) of the run's noise window, or of its
  longest static window, with the ±1σ χ² interval as a band.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from bench.calibration import CalibrationResult
from bench.estimation.allan import overlapping_allan
from bench.estimation.g_check import correct
from bench.fitted_model import FittedModel
from bench.recording import G0_M_S2, Recording

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class PreviousCalibration:
    """The unit's previous calibrated run: its id and its stored fit."""

    run_id: str
    fit: FittedModel


CHANNELS = ("ax", "ay", "az")
MIN_ALLAN_SAMPLES = 64
"""Below this a window gives too few τ points for a useful Allan curve."""


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _window_means(cal: CalibrationResult) -> FloatArray:
    return np.array([w.mean_raw for w in cal.windows], dtype=float)


def _reference(
    cal: CalibrationResult,
    nominal_scale: float | None,
    nominal_bias: Sequence[float] | None,
    previous: PreviousCalibration | None,
) -> tuple[str, FloatArray, FloatArray] | None:
    """(label, bias, K) of the 'before' model, or ``None`` when nothing is known."""
    if nominal_scale is not None:
        if not (math.isfinite(nominal_scale) and nominal_scale != 0):
            raise ValueError(f"nominal_scale must be finite and non-zero, got {nominal_scale}")
        b0 = np.zeros(3) if nominal_bias is None else np.asarray(nominal_bias, dtype=float)
        if b0.shape != (3,) or not np.all(np.isfinite(b0)):
            raise ValueError(f"nominal_bias must be 3 finite numbers, got {nominal_bias}")
        return f"nominal scale {nominal_scale:g} {cal.channel_unit}/(m/s²)", b0, nominal_scale * np.eye(3)
    if cal.channel_unit == "m/s2":
        return "uncorrected (m/s²)", np.zeros(3), np.eye(3)
    if cal.channel_unit == "g":
        return "uncorrected (g × g0)", np.zeros(3), np.eye(3) / G0_M_S2
    if previous is not None:
        label = f"previous calibration ({previous.run_id})"
        return label, np.asarray(previous.fit.bias, dtype=float), np.asarray(previous.fit.K, dtype=float)
    return None


def g_check_series(
    cal: CalibrationResult,
    *,
    nominal_scale: float | None = None,
    nominal_bias: Sequence[float] | None = None,
    previous: PreviousCalibration | None = None,
) -> dict[str, Any]:
    """|f̂| per static window before and after correction.

    :param cal: the run's calibration.
    :param nominal_scale: datasheet sensitivity (channel unit per m/s²) for 'before'.
    :param nominal_bias: (3,) datasheet zero-g output with ``nominal_scale``.
    :param previous: the unit's previous calibration, used for 'before' when no nominal scale
        applies.
    :returns: ``{"g_local_m_s2", "labels", "after_m_s2", "before_m_s2" | None,
        "before_label" | None, "after_mean_error_m_s2", "after_std_m_s2",
        "before_mean_error_m_s2", "before_std_m_s2"}``; magnitudes in m/s².
    """
    y = _window_means(cal)
    after = np.linalg.norm(correct(y, cal.bias, cal.K), axis=1)
    ref = _reference(cal, nominal_scale, nominal_bias, previous)
    before = None if ref is None else np.linalg.norm(correct(y, ref[1], ref[2]), axis=1)
    g = cal.g_local_m_s2

    def stats(m: FloatArray | None) -> tuple[float | None, float | None]:
        if m is None:
            return None, None
        e = m - g
        return _finite_or_none(float(e.mean())), _finite_or_none(float(e.std(ddof=1)) if e.size > 1 else 0.0)

    b_mean, b_std = stats(before)
    a_mean, a_std = stats(after)
    return {
        "g_local_m_s2": g,
        "labels": [w.label for w in cal.windows],
        "after_m_s2": after.tolist(),
        "before_m_s2": None if before is None else before.tolist(),
        "before_label": None if ref is None else ref[0],
        "after_mean_error_m_s2": a_mean,
        "after_std_m_s2": a_std,
        "before_mean_error_m_s2": b_mean,
        "before_std_m_s2": b_std,
    }


def residual_series(cal: CalibrationResult) -> dict[str, Any]:
    """Fit residuals per window and channel.

    :returns: ``{"channel_unit", "method", "channels", "labels", "residual": (m, 3) in channel
        units, "normalized": (m, 3) z-scores, "chi2", "dof"}``.
    """
    return {
        "channel_unit": cal.channel_unit,
        "method": cal.kind.value,
        "channels": list(CHANNELS),
        "labels": [w.label for w in cal.windows],
        "residual": [[float(v) for v in w.residual] for w in cal.windows],
        "normalized": [[_finite_or_none(float(v)) for v in w.normalized_residual] for w in cal.windows],
        "chi2": _finite_or_none(cal.chi2),
        "dof": cal.dof,
    }


def pick_noise_span(
    rec: Recording,
    noise_windows: Sequence[tuple[float, float]],
    static_windows: Sequence[tuple[float, float]],
) -> tuple[float, float, str]:
    """The span (s) for the Allan curve: the run's noise window, else its longest static window.

    :param noise_windows: (start_s, end_s) of windows recorded to measure the noise.
    :param static_windows: (start_s, end_s) of the static windows.
    :raises ValueError: neither kind of window.
    """
    if noise_windows:
        s, e = max(noise_windows, key=lambda w: w[1] - w[0])
        return s, e, "noise window"
    if static_windows:
        s, e = max(static_windows, key=lambda w: w[1] - w[0])
        return s, e, "longest static window"
    where = rec.source or "recording"
    raise ValueError(f"{where}: no noise or static window to compute an Allan curve from")


def allan_series(rec: Recording, start_s: float, end_s: float, source: str) -> dict[str, Any]:
    """Overlapping Allan deviation of the accelerometer channels between ``start_s`` and ``end_s``.

    :returns: ``{"unit", "source", "start_s", "end_s", "n_samples", "sample_rate_hz" (the
        recording's nominal rate), "ci_level", "taus_s": (m,),
        "channels", "adev", "adev_lo", "adev_hi": (c, m) lists}``; σ in channel units.
    :raises ValueError: fewer than :data:`MIN_ALLAN_SAMPLES` samples in the span.
    """
    s = int(np.searchsorted(rec.t_s, start_s, side="left"))
    e = int(np.searchsorted(rec.t_s, end_s, side="right"))
    if e - s < MIN_ALLAN_SAMPLES:
        where = rec.source or "recording"
        raise ValueError(
            f"{where}: {source} {start_s:.3f}-{end_s:.3f} s holds {max(e - s, 0)} samples; "
            f"an Allan curve needs at least {MIN_ALLAN_SAMPLES}"
        )
    res = overlapping_allan(rec.accel_raw[s:e], rec.sidecar.sample_rate_hz)
    return {
        "unit": rec.sidecar.channel_unit,
        "source": source,
        "start_s": float(rec.t_s[s]),
        "end_s": float(rec.t_s[e - 1]),
        "n_samples": e - s,
        "sample_rate_hz": rec.sidecar.sample_rate_hz,
        "ci_level": res.ci_level,
        "taus_s": res.taus_s.tolist(),
        "channels": list(CHANNELS),
        "adev": res.adev.T.tolist(),
        "adev_lo": res.adev_lo.T.tolist(),
        "adev_hi": res.adev_hi.T.tolist(),
    }
