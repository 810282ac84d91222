"""Fits for tests of what reads them (limits, certificates, exports, drift, the run observer):
a complete ``calibrate --json`` object with the keys a test does not care about filled in,
parsed as the service parses a stored fit, and a small typed fit as a run produces it."""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.calibration import CalibrationResult, FitKind
from bench.estimation.g_check import GCheck
from bench.fitted_model import FittedModel

DEFAULTS: dict[str, Any] = {
    "unit": "SN-TEST",
    "channel_unit": "V",
    "procedure": "static-12",
    "bias": [1.5, 1.5, 1.5],
    "bias_sigma": [1e-5, 1e-5, 1e-5],
    "scale_matrix": [[0.02, 0.0, 0.0], [0.0, 0.02, 0.0], [0.0, 0.0, 0.02]],
    "scale_matrix_sigma": [[1e-6] * 3] * 3,
    "terms": ["bias", "scale_matrix"],
    "extra": {},
    "residual_rms": 1e-5,
    "g_check": {"after": {"mean_error_m_s2": 0.0, "std_m_s2": 1e-4}},
}


def stored_fit(**keys: Any) -> FittedModel:
    """:data:`DEFAULTS` with ``keys`` replaced, parsed by :meth:`FittedModel.from_contract`."""
    return FittedModel.from_contract({**DEFAULTS, **keys}, "test fit")


def calibration_result(kind: FitKind = FitKind.STATIC, serial: str = "SN-TEST") -> CalibrationResult:
    """A small fit of 12 windows without window detail (``kind`` ``STATIC`` or
    ``ORIENTATION_FREE``), as a run hands it to its observers."""
    n = 12 if kind is FitKind.STATIC else 9
    errors = np.linspace(-1e-4, 1e-4, 12)
    g_after = GCheck(9.81 + errors, errors, float(errors.mean()), float(errors.std(ddof=1)), 1e-4)
    return CalibrationResult(
        unit_serial=serial,
        channel_unit="V",
        procedure="static-12",
        kind=kind,
        g_local_m_s2=9.81,
        bias=np.array([1.5, 1.49, 1.51]),
        K=np.diag([0.02, 0.021, 0.019]),
        cov=np.eye(n) * 1e-10,
        bias_sigma=np.full(3, 1e-5),
        K_sigma=np.full((3, 3), 1e-6),
        residual_rms=2e-5,
        chi2=20.0,
        dof=24 if kind is FitKind.STATIC else 3,
        noise_model="white",
        g_after=g_after,
        g_before=None,
        windows=(),
    )
