"""The signal as it comes, for a live view: the last ``span_s`` seconds of a run's samples,
decimated to at most ``max_points`` points, in memory bounded whatever the run's length.

Decimation is by block means: ``k = ceil(rate · span_s / max_points)`` consecutive samples
become one point, at the mean of their time stamps, channels and table angles (a boxcar
filter before subsampling, so noise is averaged rather than aliased; each angle taken within
±180° of the block's first, so a block across the ±180° wrap stays at the wrap). A block split between
two sample blocks of the DAQ is completed by the next one. The view holds at most
``max_points`` points and fewer than ``k`` carried samples: ``O(max_points + k)`` numbers per
run. It only reads what the recording was given; the recording itself is never decimated.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

CHANNELS = ("ax", "ay", "az")
Samples = NDArray[np.float64]
"""A block of samples as the recording took it: times (n,), channels (n, 3) or angles (n, n_axes)."""


@dataclass(frozen=True)
class SignalView:
    """The decimated tail of a run's signal.

    :param t_s: point times on the recording clock (s), increasing; shape (n,).
    :param accel: channel means per point in the recording's units; shape (n, 3) (ax, ay, az).
    :param table_deg: mean table angles per point (deg, outermost axis first); shape (n, n_axes).
    :param samples_per_point: ``k``, the samples averaged into one point.
    :param span_s: the span the view keeps (s).
    """

    t_s: tuple[float, ...]
    accel: tuple[tuple[float, ...], ...]
    table_deg: tuple[tuple[float, ...], ...]
    samples_per_point: int
    span_s: float


class SignalTail:
    """Bounded, decimated buffer of the last ``span_s`` seconds of samples.

    :param sample_rate_hz: the DAQ's rate (Hz).
    :param span_s: how much of the signal the view shows (s).
    :param max_points: most points kept (so at most ``max_points`` per channel are sent).
    """

    def __init__(self, sample_rate_hz: float, span_s: float = 30.0, max_points: int = 300) -> None:
        if not (sample_rate_hz > 0 and span_s > 0 and max_points >= 2):
            raise ValueError(
                f"SignalTail: sample_rate_hz {sample_rate_hz}, span_s {span_s}, max_points {max_points}: "
                "expected positive rate and span and at least 2 points"
            )
        self.span_s = float(span_s)
        self.samples_per_point = max(1, math.ceil(sample_rate_hz * span_s / max_points))
        self._points: deque[NDArray[np.float64]] = deque(maxlen=max_points)
        self._carry: NDArray[np.float64] | None = None  # < k rows [t, ax, ay, az, angles...]

    def add(self, t_s: Samples, accel: Samples, table_deg: Samples) -> None:
        """Append a block: ``t_s`` shape (n,), ``accel`` (n, 3), ``table_deg`` (n, n_axes).

        :raises ValueError: the shapes disagree.
        """
        t = np.asarray(t_s, dtype=float).reshape(-1, 1)
        a = np.asarray(accel, dtype=float)
        d = np.asarray(table_deg, dtype=float)
        if a.shape != (len(t), 3) or d.ndim != 2 or len(d) != len(t):
            raise ValueError(
                f"SignalTail.add: t_s {t.shape[0]} samples, accel {a.shape}, table_deg {d.shape}: "
                "expected (n,), (n, 3), (n, n_axes)"
            )
        rows = np.hstack([t, a, d])
        if self._carry is not None and self._carry.shape[1] == rows.shape[1]:
            rows = np.vstack([self._carry, rows])
        k = self.samples_per_point
        full = len(rows) // k * k
        if full:
            blocks = rows[:full].reshape(-1, k, rows.shape[1])
            means = blocks.mean(axis=1)
            # angles: each sample taken to within ±180° of its block's first before the mean,
            # so a block across the ±180° wrap averages to the wrap, not to 0
            first = blocks[:, :1, 4:]
            means[:, 4:] = (first + ((blocks[:, :, 4:] - first + 180.0) % 360.0 - 180.0)).mean(axis=1)
            for row in means[-(self._points.maxlen or len(means)) :]:
                self._points.append(row.copy())
        self._carry = rows[full:] if full < len(rows) else None

    def view(self) -> SignalView:
        """The points within ``span_s`` of the newest one (a hold or a gap leaves none older)."""
        pts = list(self._points)
        if pts:
            newest = pts[-1][0]
            pts = [p for p in pts if p[0] >= newest - self.span_s]
        return SignalView(
            tuple(float(p[0]) for p in pts),
            tuple(tuple(float(v) for v in p[1:4]) for p in pts),
            tuple(tuple(float(v) for v in p[4:]) for p in pts),
            self.samples_per_point,
            self.span_s,
        )


def view_to_json(view: SignalView, digits: int = 7) -> dict[str, object]:
    """The ``signal`` event's data: ``t_s``, one list per channel (``ax``, ``ay``, ``az``),
    ``table_deg`` (one list per axis), ``samples_per_point`` and ``span_s``; values rounded to
    ``digits`` significant digits (a view, not the record), a value that is not finite as
    ``null``."""

    def r(v: float) -> float | None:
        return float(f"{v:.{digits}g}") if math.isfinite(v) else None

    n_axes = len(view.table_deg[0]) if view.table_deg else 0
    return {
        "t_s": [r(t) for t in view.t_s],
        **{c: [r(a[i]) for a in view.accel] for i, c in enumerate(CHANNELS)},
        "table_deg": [[r(d[i]) for d in view.table_deg] for i in range(n_axes)],
        "samples_per_point": view.samples_per_point,
        "span_s": view.span_s,
    }
