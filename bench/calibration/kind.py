"""The kind of fit a recording gets, chosen once (:func:`bench.calibration.calibrate_recording`)
and carried by the fit (``CalibrationResult.kind``) to everything that reads it.
:class:`FitKind` is :class:`bench.fit_kind.FitKind` (with how a stored fit states its kind).

* :attr:`FitKind.MOVING`: the table turns while the DAQ samples (:func:`is_moving`): the
  sample-by-sample dynamic fit (``bench.calibration.dynamic``), p = 12 + extra terms;
* :attr:`FitKind.STATIC`: still windows whose specific force is known (a table in the sidecar,
  or every window labelled ``nominal_up``): the 12-parameter known-orientation fit;
* :attr:`FitKind.ORIENTATION_FREE`: still windows of unknown orientation: the 9-parameter fit of
  |f| = g (K as the lower-triangular L, K up to a rotation).

The values are the names the database's ``fit.kind`` column stores. This module imports no
fit, so choosing costs nothing (the moving fit's stack, ``scipy.signal`` among it, is imported
only for a moving recording).
"""

from __future__ import annotations

import numpy as np

from bench.calibration.windows import MAX_TABLE_MOTION_RAD
from bench.fit_kind import FitKind
from bench.recording import Recording

__all__ = ["CANDIDATE_TERMS", "MOVING_PROCEDURES", "STATIC_PROCEDURES", "FitKind", "is_moving"]

MOVING_PROCEDURES = ("rate-1axis", "oscillation-2axis", "planned-tumble")
"""calbench's procedures whose table moves while it records."""
STATIC_PROCEDURES = ("static-12", "planned-static")
"""calbench's procedures that record only while the table is still (with
:data:`MOVING_PROCEDURES`, every name of ``bench.procedures.PROCEDURES``; a test holds them
together)."""
CANDIDATE_TERMS = ("lever_arm", "proof_mass_offsets", "nonlinearity_quadratic", "table_tilt", "time_skew")
"""The moving fit's terms beyond bias and K (``calbench calibrate --terms``)."""


def is_moving(rec: Recording) -> bool:
    """A moving-table recording: one of calbench's moving procedures, or, for a recording of no
    procedure or of a procedure calbench does not know (the sidecar's ``procedure`` is free text
    from another bench), a declared segment in which the encoder angles span more than
    ``MAX_TABLE_MOTION_RAD``. calbench's own static procedures are static whatever their
    segments hold (a segment that moved is named unused by the window fit)."""
    proc = rec.sidecar.procedure
    if proc in MOVING_PROCEDURES:
        return True
    if proc in STATIC_PROCEDURES or rec.table_deg is None or not rec.sidecar.segments:
        return False
    q = rec.table_rad_unwrapped()
    assert q is not None
    for s in rec.sidecar.segments:
        sel = (rec.t_s >= s.start_s) & (rec.t_s <= s.end_s)
        if sel.sum() > 1 and np.max(np.ptp(q[sel], axis=0)) > MAX_TABLE_MOTION_RAD:
            return True
    return False
