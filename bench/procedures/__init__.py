"""Calibration procedures as data, by name.

``build_procedure("static-12", dwell_s=None)`` returns a :class:`Procedure` (a tuple of
steps); the sequencer executes it, :func:`preview` dry-runs it; :func:`check_procedure`
builds and previews a request to run one and says what refuses it.
"""

from __future__ import annotations

from bench.procedures.preview import DEFAULT_TABLE_LIMITS, Preview, TableLimits, preview
from bench.procedures.registry import (
    PROCEDURES,
    Admitted,
    ProcedureRefused,
    Refusal,
    RefusalKind,
    admit_procedure,
    build_procedure,
    check_procedure,
)
from bench.procedures.steps import Dwell, MoveTo, NoiseWindow, Oscillate, Procedure, Rotate, Step

__all__ = [
    "DEFAULT_TABLE_LIMITS",
    "PROCEDURES",
    "Admitted",
    "Dwell",
    "MoveTo",
    "NoiseWindow",
    "Oscillate",
    "Preview",
    "Procedure",
    "ProcedureRefused",
    "Refusal",
    "RefusalKind",
    "Rotate",
    "Step",
    "TableLimits",
    "admit_procedure",
    "build_procedure",
    "check_procedure",
    "preview",
]
