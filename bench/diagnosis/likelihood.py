"""Gaussian likelihood of the stacked window means, as the diagnosis uses it.

The model and GLS live in ``bench.estimation.slow_noise``, the REML noise estimation in
``bench.estimation.noise_reml`` (the calibration uses them too); this module names them for the diagnosis.
"""

from __future__ import annotations

from bench.estimation.noise_reml import CORRELATION_TIMES_FRACTION, fit_noise
from bench.estimation.slow_noise import (
    GlsFit,
    NoiseParams,
    correlation,
    covariance,
    gls,
    window_covariance,
    without_excess,
    without_pose,
)

__all__ = [
    "CORRELATION_TIMES_FRACTION",
    "GlsFit",
    "NoiseParams",
    "correlation",
    "covariance",
    "fit_noise",
    "gls",
    "window_covariance",
    "without_excess",
    "without_pose",
]
