"""Faults the simulated table can be told to show, with their parameters and defaults.

=================  ==========================================================================
fault              effect
=================  ==========================================================================
``no_reply``       the server reads commands but answers nothing (a hung controller)
``garbled``        each reply is corrupted with ``probability`` (bytes outside printable
                   ASCII replace some characters; the terminator survives)
``stalled_axis``   ``axis`` (1 = outermost) jams: it stops dead and follows no demand; a
                   following-error trip (mode OFF, error 100·wire_axis + 3) comes ``trip_s``
                   simulated seconds after the planned end of the motion it could not make
``interlock_trip`` ``after_s`` simulated seconds from now every interlock goes to Fault, every
                   axis brakes to rest, modes go OFF, error 100·wire_axis + 9 per axis
``slow_settle``    moves end with damped ringing (``peak_deg``, ``frequency_hz``,
                   ``decay_s``): the true angle rings and in-position comes late
=================  ==========================================================================
"""

from __future__ import annotations

import math
from typing import Any

FAULTS: dict[str, dict[str, Any]] = {
    "no_reply": {},
    "garbled": {"probability": 1.0},
    "stalled_axis": {"axis": None, "trip_s": 1.0},
    "interlock_trip": {"after_s": 0.0},
    "slow_settle": {"peak_deg": 0.05, "frequency_hz": 2.0, "decay_s": 2.0},
}
"""Fault name -> parameter defaults (``None``: required)."""


def check_fault_params(fault: str, params: dict[str, Any], n_axes: int) -> dict[str, Any]:
    """The fault's parameters with defaults filled in.

    :raises ValueError: unknown fault or parameter, a missing required one, or a bad value.
    """
    if fault not in FAULTS:
        raise ValueError(f"unknown fault {fault!r}; known: {sorted(FAULTS)}")
    defaults = FAULTS[fault]
    unknown = set(params) - set(defaults)
    if unknown:
        raise ValueError(
            f"fault {fault!r}: unknown parameter(s) {sorted(unknown)}; known: {sorted(defaults)}"
        )
    full = {**defaults, **params}
    missing = [k for k, v in full.items() if v is None]
    if missing:
        raise ValueError(f"fault {fault!r}: missing parameter(s) {missing}")
    for name, value in full.items():
        if name == "axis":
            if not isinstance(value, int) or not 1 <= value <= n_axes:
                raise ValueError(
                    f"fault {fault!r}: axis must be an int in 1..{n_axes} (1 = outermost), got {value!r}"
                )
            continue
        if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
            raise ValueError(f"fault {fault!r}: {name} must be a finite number >= 0, got {value!r}")
    if fault == "garbled" and full["probability"] > 1:
        raise ValueError(f"fault 'garbled': probability must be in 0..1, got {full['probability']!r}")
    if fault == "slow_settle" and min(full["peak_deg"], full["frequency_hz"], full["decay_s"]) <= 0:
        raise ValueError(f"fault 'slow_settle': peak_deg, frequency_hz, decay_s must be > 0, got {full}")
    return full
