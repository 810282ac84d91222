"""Calibration of a recording: windows -> window noise -> fit -> typed result -> analysis.

Modules, one concept each:

* ``windows``: which windows a recording offers, their means and honest covariances, their
  mean encoder angles and the specific force each saw (one copy, used by all below);
* ``kind``: :class:`FitKind`, the kind of fit a recording gets (static, orientation-free,
  moving), chosen once;
* ``result``: :class:`CalibrationResult` / :class:`WindowResult`, and the contract object;
* ``static``: the known-orientation and orientation-free fits of the windows;
* ``dynamic``: the sample-by-sample fit of a moving-table recording;
* ``recording``: :func:`calibrate_recording`, which chooses between them;
* ``analysis``: :func:`analyse`, a recording read once and fitted once, with what every
  consumer of the fit needs (the nominal |g| check, the budget's design, the diagnosis);
* ``diagnose``: the same windows handed to ``bench.diagnosis``.

The names below are the package's public face; import them from ``bench.calibration``. The
moving fit's names (``calibrate_dynamic``, ``DynamicCalibrationResult``) are imported on first
use, so a static recording's calibration never loads the moving fit's stack.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from bench.calibration.kind import FitKind, is_moving
from bench.calibration.recording import calibrate_recording
from bench.calibration.result import CalibrationResult, WindowResult
from bench.calibration.static import NATURAL_ZERO_UNITS
from bench.calibration.windows import select_windows, window_means

if TYPE_CHECKING:
    from bench.calibration.dynamic import DynamicCalibrationResult, calibrate_dynamic

__all__ = [
    "NATURAL_ZERO_UNITS",
    "CalibrationResult",
    "DynamicCalibrationResult",
    "FitKind",
    "WindowResult",
    "calibrate_dynamic",
    "calibrate_recording",
    "is_moving",
    "select_windows",
    "window_means",
]

_MOVING = ("DynamicCalibrationResult", "calibrate_dynamic")


def __getattr__(name: str) -> Any:
    """The moving fit's names, imported when first asked for (PEP 562)."""
    if name in _MOVING:
        from bench.calibration import dynamic

        return getattr(dynamic, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
