"""What the wire models of every resource share: the run state vocabulary, the serial pattern, the
largest paging offset, the shortest dwell, and the text rule of stored text
(:func:`bench.inputs.check_text`)."""

from __future__ import annotations

from bench.inputs import InputError, check_text
from bench.run_state import RunState

RunStateName = RunState
"""A run's state on the wire: the values of the one run vocabulary (``bench.run_state.RunState``)."""
SERIAL_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"
MAX_PAGE_OFFSET = 2**53
"""Largest paging offset a list accepts: a 64-bit database integer holds it on every backend
(SQLite refuses a Python int beyond 2**63 - 1 with an OverflowError), and no table nears it."""
MIN_DWELL_S = 0.5
"""Shortest static dwell a run may ask for (s): shorter windows hold too few samples to fit."""


def stored_text(value: str | None, *, multiline: bool = False) -> str | None:
    """``value`` when it passes the stored-text rules (``None`` passes).

    :raises ValueError: NUL, control or bidi-control characters (the message names the rule).
    """
    if value is None:
        return None
    try:
        return check_text(value, multiline=multiline)
    except InputError as exc:
        raise ValueError(str(exc)) from None
