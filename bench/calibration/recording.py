"""Calibrate a recording: the one place where a :class:`~bench.recording.Recording` becomes a
calibration; the CLI (``calbench calibrate``), the service and ``diagnose`` all call
:func:`calibrate_recording`.

The kind of fit is chosen here, once (``kind.FitKind``): a moving-table recording
(``kind.is_moving``: a ``rate-1axis`` or ``oscillation-2axis`` procedure, or no procedure and a
segment in which the table turns) gets the sample-by-sample dynamic fit
(``dynamic.calibrate_dynamic``, imported only then); every other one the static or
orientation-free fit of its windows (``static.calibrate_static``). Either passes the
plausibility checks of ``bench.recording.plausibility`` before and after its fit; what they
find is added to the result's ``warnings``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import numpy.typing as npt

from bench.calibration.kind import FitKind, is_moving
from bench.calibration.result import CalibrationResult
from bench.calibration.static import NATURAL_ZERO_UNITS, calibrate_static
from bench.calibration.windows import where
from bench.recording import Recording
from bench.recording.plausibility import Finding, fit_findings, recording_findings

FloatArray = npt.NDArray[np.float64]


def calibrate_recording(
    rec: Recording,
    *,
    nominal_scale: float | None = None,
    nominal_bias: FloatArray | None = None,
    terms: tuple[str, ...] | None = None,
) -> CalibrationResult:
    """Fit bias and scale/misalignment to a recording (see the module docstring).

    :param rec: the recording.
    :param nominal_scale: nominal sensitivity (channel unit per m/s²) for the "before"
        g check of a channel unit without a natural scale (V, count).
    :param nominal_bias: (3,) nominal zero-g output (channel units) with ``nominal_scale``;
        required with it unless the channel unit is in :data:`NATURAL_ZERO_UNITS`.
    :param terms: a moving recording's declared extra terms (``calbench calibrate --terms``);
        ``None``: the terms its evidence supports.
    :returns: :class:`CalibrationResult`.
    :raises ValueError: a nominal scale without a zero-g output for a V or count channel, no
        usable windows, a degenerate orientation set (the message names the undeterminable
        parameters), too few windows for the scalar fit, or non-finite data; every message
        starts with the recording's path.
    """
    try:
        unit = rec.sidecar.channel_unit
        if nominal_scale is not None and nominal_bias is None and unit not in NATURAL_ZERO_UNITS:
            raise ValueError(
                f"a nominal scale for a {unit} channel needs the nominal zero-g output (nominal_bias): "
                f"a {unit} output is not 0 at zero g"
            )
        found = recording_findings(rec)
        if is_moving(rec):
            from bench.calibration.dynamic import calibrate_dynamic  # the moving fit's stack, only here

            result: CalibrationResult = calibrate_dynamic(
                rec, terms=terms, nominal_scale=nominal_scale, nominal_bias=nominal_bias
            )
            return with_plausibility(result, rec, found)
        if terms is not None:
            raise ValueError("--terms applies to moving-table recordings; this one is static")
        return with_plausibility(calibrate_static(rec, nominal_scale, nominal_bias), rec, found)
    except ValueError as exc:
        msg = str(exc)
        where_ = where(rec)
        raise ValueError(msg if msg.startswith(where_) else f"{where_}: {msg}") from exc


def with_plausibility(
    result: CalibrationResult, rec: Recording, found: tuple[Finding, ...] | None = None
) -> CalibrationResult:
    """``result`` with the plausibility findings of its recording (``found``, else computed) and
    of its fitted model added to ``warnings``."""
    if found is None:
        found = recording_findings(rec)
    skew = getattr(result, "extra", {}).get("time_skew", {}).get("delay_s")
    after = fit_findings(
        result.K,
        frame_known=result.kind is not FitKind.ORIENTATION_FREE,
        channel_unit=result.channel_unit,
        time_skew_s=float(skew) if skew is not None else None,
        sample_rate_hz=rec.sidecar.sample_rate_hz,
    )
    texts = [f.text for f in (*found, *after)]
    return replace(result, warnings=(*result.warnings, *texts)) if texts else result
