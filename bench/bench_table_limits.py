"""The ``[table.limits]`` section of a bench file: what this table can do, per axis.

Each table has its own rates, accelerations, travel and settling; every check of a procedure
against the table (start, queue, preview, resume, the sequencer's move deadlines, the planner)
uses the limits of the bench that runs, read here from its file
(:meth:`bench.bench_config.BenchConfig.table_limits`). A file without the section runs with
:data:`bench.procedures.preview.DEFAULT_TABLE_LIMITS`. Format (lists: one entry per axis,
outermost first, as many as ``[[table.axes]]``)::

    [table.limits]
    max_rate_deg_s = [300.0, 200.0, 300.0]     # rate limit (deg/s), required
    max_acc_deg_s2 = [200.0, 200.0, 200.0]     # acceleration limit (deg/s²), required
    continuous = [true, false, true]           # slip ring: turns without end, required
    travel_deg = [[-180, 180], [-120, 120], [-180, 180]]   # optional; default ±180 each
    settle_s = 2.0                # optional: ring-down after in-position (s); 0: not stated

Refused, naming the key: a list of the wrong length, a value that is not a finite number (or
a boolean for ``continuous``), a rate outside (0, :data:`MAX_RATE_DEG_S`], an acceleration
outside (0, :data:`MAX_ACC_DEG_S2`], a travel not ``lo < hi`` within ±:data:`MAX_TRAVEL_DEG`, a
settling outside [0, :data:`MAX_SETTLE_S`].
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from bench.procedures.preview import TableLimits

KEYS = {"max_rate_deg_s", "max_acc_deg_s2", "continuous", "travel_deg", "settle_s"}
MAX_RATE_DEG_S = 36000.0
"""Highest rate limit accepted (deg/s, 100 turns per second): beyond it a value is a typo."""
MAX_ACC_DEG_S2 = 1.0e6
"""Highest acceleration limit accepted (deg/s²)."""
MAX_TRAVEL_DEG = 180.0
"""Travel limits lie within ± this (deg): angles are commanded, and read back, within ±180."""
MAX_SETTLE_S = 600.0
"""Longest settling accepted (s)."""

Fail = Callable[[str, str], Exception]
"""``fail(key, message)``: the error naming the file and ``table.limits.<key>``."""


def parse_table_limits(doc: Any, n_axes: int, fail: Fail) -> TableLimits:
    """The ``[table.limits]`` table ``doc`` of a bench with ``n_axes`` axes.

    :param fail: builds the refusal for a key (relative to ``table.limits``) and a message.
    :raises Exception: what ``fail`` builds, for the first rule broken.
    """
    if not isinstance(doc, dict):
        raise fail("", f"must be a table, got {type(doc).__name__}")
    unknown = sorted(set(doc) - KEYS)
    if unknown:
        raise fail(unknown[0], f"unknown key; expected one of {', '.join(sorted(KEYS))}")

    def per_axis(name: str, default: Any = ...) -> list[Any]:
        if name not in doc:
            if default is ...:
                raise fail(name, f"missing (one value per axis, {n_axes})")
            return [default] * n_axes
        v = doc[name]
        if not isinstance(v, list) or len(v) != n_axes:
            raise fail(name, f"must list one value per axis ({n_axes}, outermost first), got {v!r}")
        return v

    def number(name: str, v: Any, lo: float, hi: float, *, lo_open: bool = True) -> float:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(float(v)):
            raise fail(name, f"must be a finite number, got {v!r}")
        x = float(v)
        if not (lo < x if lo_open else lo <= x) or x > hi:
            raise fail(name, f"must be in {'(' if lo_open else '['}{lo:g}, {hi:g}], got {x:g}")
        return x

    rates = tuple(
        number(f"max_rate_deg_s[{i}]", v, 0.0, MAX_RATE_DEG_S)
        for i, v in enumerate(per_axis("max_rate_deg_s"))
    )
    accs = tuple(
        number(f"max_acc_deg_s2[{i}]", v, 0.0, MAX_ACC_DEG_S2)
        for i, v in enumerate(per_axis("max_acc_deg_s2"))
    )
    continuous = per_axis("continuous")
    for i, c in enumerate(continuous):
        if not isinstance(c, bool):
            raise fail(f"continuous[{i}]", f"must be true or false, got {c!r}")
    lo_deg: list[float] = []
    hi_deg: list[float] = []
    for i, t in enumerate(per_axis("travel_deg", [-180.0, 180.0])):
        key = f"travel_deg[{i}]"
        if not isinstance(t, list) or len(t) != 2:
            raise fail(key, f"must be [lowest, highest] (deg), got {t!r}")
        lo = number(key, t[0], -MAX_TRAVEL_DEG, MAX_TRAVEL_DEG, lo_open=False)
        hi = number(key, t[1], -MAX_TRAVEL_DEG, MAX_TRAVEL_DEG, lo_open=False)
        if not lo < hi:
            raise fail(key, f"lowest must be below highest, got [{lo:g}, {hi:g}] deg")
        lo_deg.append(lo)
        hi_deg.append(hi)
    settle = number("settle_s", doc.get("settle_s", 0.0), 0.0, MAX_SETTLE_S, lo_open=False)
    return TableLimits(tuple(lo_deg), tuple(hi_deg), rates, accs, tuple(continuous), settle)
