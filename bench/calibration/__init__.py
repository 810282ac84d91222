"""Calibration of a recording: windows -> window noise -> fit -> typed result.

Modules, one concept each:

* ``windows``: which windows a recording offers, their means and honest covariances, their
  mean encoder angles and the specific force each saw (one copy, used by all below);
* ``result``: :class:`CalibrationResult` / :class:`WindowResult`, and the contract object;
* ``static``: the known-orientation and orientation-free fits of the windows;
* ``dynamic``: the sample-by-sample fit of a moving-table recording;
* ``recording``: :func:`calibrate_recording`, which chooses between them;
* ``diagnose``: the same windows handed to ``bench.diagnosis``.

The names below are the package's public face; import them from ``bench.calibration``.
"""

from bench.calibration.dynamic import DynamicCalibrationResult, calibrate_dynamic, is_dynamic
from bench.calibration.recording import calibrate_recording
from bench.calibration.result import CalibrationResult, WindowResult
from bench.calibration.static import NATURAL_ZERO_UNITS
from bench.calibration.windows import select_windows, window_means

__all__ = [
    "NATURAL_ZERO_UNITS",
    "CalibrationResult",
    "DynamicCalibrationResult",
    "WindowResult",
    "calibrate_dynamic",
    "calibrate_recording",
    "is_dynamic",
    "select_windows",
    "window_means",
]
