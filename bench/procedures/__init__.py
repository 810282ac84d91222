"""Calibration procedures as data, by name.

``build_procedure("static-12", dwell_s=None)`` returns a :class:`Procedure` (a tuple of
steps); the sequencer executes it, :func:`preview` dry-runs it.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

from bench.procedures.oscillation import oscillation_2axis
from bench.procedures.planned import planned_static, planned_tumble
from bench.procedures.preview import DEFAULT_TABLE_LIMITS, Preview, TableLimits, preview
from bench.procedures.rate import rate_1axis
from bench.procedures.static import static_12
from bench.procedures.steps import Dwell, MoveTo, NoiseWindow, Oscillate, Procedure, Rotate, Step

PROCEDURES: dict[str, Callable[..., Procedure]] = {
    "static-12": static_12,
    "rate-1axis": rate_1axis,
    "oscillation-2axis": oscillation_2axis,
    "planned-static": planned_static,
    "planned-tumble": planned_tumble,
}
"""Registry: procedure name -> factory taking ``dwell_s`` (``None``: noise window first)."""


def build_procedure(name: str, dwell_s: float | None = None, **parameters: object) -> Procedure:
    """Build a registered procedure.

    :raises ValueError: unknown name (the message lists the known ones), or a parameter the
        procedure does not take (named, with the ones it takes).
    """
    try:
        factory = PROCEDURES[name]
    except KeyError:
        raise ValueError(f"unknown procedure {name!r}; known: {', '.join(sorted(PROCEDURES))}") from None
    accepted = set(inspect.signature(factory).parameters) - {"dwell_s"}
    unknown = sorted(set(parameters) - accepted)
    if unknown:
        raise ValueError(
            f"procedure {name!r} takes no parameter {', '.join(unknown)}; "
            f"it takes: {', '.join(sorted(accepted)) or 'none'}"
        )
    return factory(dwell_s=dwell_s, **parameters)


__all__ = [
    "DEFAULT_TABLE_LIMITS",
    "PROCEDURES",
    "Dwell",
    "MoveTo",
    "NoiseWindow",
    "Oscillate",
    "Preview",
    "Procedure",
    "Rotate",
    "Step",
    "TableLimits",
    "build_procedure",
    "preview",
]
