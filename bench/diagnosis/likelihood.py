"""Gaussian likelihood of the stacked window means, as the diagnosis uses it.

The model, GLS and REML noise estimation live in ``bench.estimation.slow_noise`` (the
calibration uses them too); this module names them for the diagnosis.
"""

from __future__ import annotations

from bench.estimation.slow_noise import (
    CORRELATION_TIMES_FRACTION,
    GlsFit,
    NoiseParams,
    correlation,
    covariance,
    fit_noise,
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
