"""Exports of a fitted model with the noise a Kalibr YAML needs, from the run's Allan curve.

Kalibr's accelerometer noise parameters, from the overlapping Allan deviation σ(τ) of a static
stretch (``api.plots.run_series.allan_series``, channel units), converted with K_ii to m/s²
(IEEE Std 952 Annex C; Kalibr wiki "IMU Noise Model"):

* noise density N = σ(τ₀)·√τ₀ at the shortest τ (white noise: σ(τ) = N/√τ), m/s²/√Hz;
* random walk K ≤ σ(τ_m)·√(3/τ_m) at the longest τ (random walk: σ(τ) = K·√(τ/3)), m/s³/√Hz,
  an upper bound where the curve has not reached its +½ slope;

each the largest of the three channels (Kalibr has one value per sensor).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.export import FORMATS, to_c_header, to_imucal, to_json, to_kalibr
from bench.fitted_model import FittedModel


def kalibr_noise(allan: Mapping[str, Any], fit: FittedModel) -> tuple[float, float, float]:
    """(sample rate Hz, noise density m/s²/√Hz, random walk m/s³/√Hz) from an Allan series.

    :raises ValueError: the series is too short or holds no finite value.
    """
    taus = np.asarray(allan["taus_s"], float)
    adev = np.asarray(allan["adev"], float)
    K = np.asarray(fit.K, float)
    if taus.size < 2 or adev.shape != (3, taus.size):
        raise ValueError("the Allan curve is too short to give Kalibr's noise parameters")
    span = float(allan["end_s"]) - float(allan["start_s"])
    rate = (int(allan["n_samples"]) - 1) / span if span > 0 else math.nan
    scale = np.abs(np.diag(K))[:, None]
    sig = adev / scale  # m/s2
    density = float(np.nanmax(sig[:, 0] * math.sqrt(taus[0])))
    walk = float(np.nanmax(sig[:, -1] * math.sqrt(3.0 / taus[-1])))
    if not (math.isfinite(density) and math.isfinite(walk) and math.isfinite(rate)):
        raise ValueError("the Allan curve gives no finite noise values")
    return rate, density, walk


def export_text(fmt: str, fit: FittedModel, allan: Mapping[str, Any] | None, source: str) -> str:
    """The export ``fmt`` of a fit (``allan``: the run's Allan series, needed by ``kalibr``).

    :raises ValueError: unknown format, a bad model, or ``kalibr`` without an Allan curve.
    """
    if fmt == "imucal":
        return to_imucal(fit, source)
    if fmt == "c-header":
        return to_c_header(fit, source)
    if fmt == "json":
        return to_json(fit, source)
    if fmt == "kalibr":
        if allan is None:
            raise ValueError(
                "the Kalibr export needs the run's Allan curve (a static stretch of the recording)"
            )
        rate, density, walk = kalibr_noise(allan, fit)
        return to_kalibr(fit, sample_rate_hz=rate, noise_density_m_s2_sqrt_hz=density,
                         random_walk_m_s3_sqrt_hz=walk, source=source)  # fmt: skip
    raise ValueError(f"unknown export format {fmt!r}; known: {', '.join(FORMATS)}")
