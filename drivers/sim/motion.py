"""Motion profiles of a rotary table: what each axis does as a function of time.

Everything here is pure and vectorised: a segment (``drivers/sim/motion_segments.py``,
re-exported here) evaluates ``(angle_rad, rate_rad_s, accel_rad_s2)`` at an array of
times, an :class:`AxisProfile` chains segments, and a :class:`TableProfile` evaluates all
axes at once into a :class:`TableKinematics`.

Angles are the controller's own (encoder) coordinates in radians; the physics model
(``drivers/sim/physics.py``) turns them into the true table state (encoder offset,
settling). Each segment carries its own start angle; an :class:`AxisProfile` checks that
consecutive segments join in angle.

Beyond its duration a segment extrapolates physically: a hold or a finished move stays
where it ended, a constant rate keeps turning, an oscillation keeps oscillating.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drivers.sim.motion_segments import (
    ConstantRate,
    Evaluation,
    FloatArray,
    Hold,
    Oscillation,
    Segment,
    TrapezoidMove,
    end_state,
)

__all__ = [
    "JOIN_TOL_RAD",
    "AxisProfile",
    "ConstantRate",
    "Evaluation",
    "FloatArray",
    "Hold",
    "Oscillation",
    "Segment",
    "TableKinematics",
    "TableProfile",
    "TrapezoidMove",
    "end_state",
]

JOIN_TOL_RAD = 1e-9
"""Largest angle jump (rad) tolerated between consecutive segments of one axis."""


@dataclass(frozen=True)
class TableKinematics:
    """State of every table axis at a set of times (controller coordinates).

    :param t_s: (n,) times (s).
    :param angles_rad: (n, k) axis angles, axes outermost first (rad).
    :param rates_rad_s: (n, k) axis rates (rad/s).
    :param accels_rad_s2: (n, k) axis angular accelerations (rad/s²).
    :param since_rest_s: (n, k) time since the axis came to rest after its last motion (s);
        ``inf`` while it moves and before it has moved at all. ``None`` when unknown. The
        physics model needs it for the ``settling`` effect (ringing after a move).
    """

    t_s: FloatArray
    angles_rad: FloatArray
    rates_rad_s: FloatArray
    accels_rad_s2: FloatArray
    since_rest_s: FloatArray | None = None

    @property
    def n_axes(self) -> int:
        """Number of table axes k."""
        return int(self.angles_rad.shape[1])

    def angles_deg(self) -> FloatArray:
        """(n, k) axis angles in degrees (unwrapped)."""
        return np.rad2deg(self.angles_rad)


@dataclass(frozen=True)
class AxisProfile:
    """One axis's motion: segments run back to back from ``start_s``.

    Before ``start_s`` the axis is in its first segment's initial state; after the last
    segment that segment extrapolates (see the module docstring).
    """

    segments: tuple[Segment, ...]
    start_s: float = 0.0
    _starts_s: FloatArray = field(init=False, repr=False, compare=False)
    _rest_origin_s: tuple[float | None, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.segments:
            raise ValueError("AxisProfile: at least one segment is needed")
        object.__setattr__(self, "segments", tuple(self.segments))
        for i in range(1, len(self.segments)):
            prev_end, _ = end_state(self.segments[i - 1])
            if abs(self.segments[i].start_rad - prev_end) > JOIN_TOL_RAD:
                raise ValueError(
                    f"AxisProfile: segment {i} starts at {self.segments[i].start_rad!r} rad but segment "
                    f"{i - 1} ends at {prev_end!r} rad"
                )
        durations = np.array([s.duration_s for s in self.segments], dtype=float)
        starts = self.start_s + np.concatenate(([0.0], np.cumsum(durations)[:-1]))
        object.__setattr__(self, "_starts_s", starts)
        # For each segment: the absolute time its current rest began (None: never moved yet).
        origins: list[float | None] = []
        last_motion_end: float | None = None
        for seg, s0 in zip(self.segments, starts, strict=True):
            rest_from = seg.rest_from_s
            if rest_from is None:
                origins.append(None)
                last_motion_end = float(s0 + seg.duration_s)
            elif rest_from > 0.0:
                last_motion_end = float(s0 + rest_from)
                origins.append(last_motion_end)
            else:
                origins.append(last_motion_end)
        object.__setattr__(self, "_rest_origin_s", tuple(origins))

    @property
    def duration_s(self) -> float:
        """Total length of all segments (s)."""
        return float(sum(s.duration_s for s in self.segments))

    @property
    def end_s(self) -> float:
        """Time the last segment ends (s)."""
        return self.start_s + self.duration_s

    def then(self, segment: Segment) -> AxisProfile:
        """A new profile with ``segment`` appended."""
        return AxisProfile((*self.segments, segment), self.start_s)

    def evaluate(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(angle_rad, rate_rad_s, accel_rad_s2, since_rest_s) at times ``t_s`` (n,)."""
        t = np.asarray(t_s, dtype=float)
        idx = np.clip(np.searchsorted(self._starts_s, t, side="right") - 1, 0, len(self.segments) - 1)
        angle = np.empty_like(t)
        rate = np.empty_like(t)
        accel = np.empty_like(t)
        since_rest = np.full_like(t, np.inf)
        for j in np.unique(idx):
            mask = idx == j
            seg = self.segments[j]
            tau = np.maximum(t[mask] - self._starts_s[j], 0.0)
            angle[mask], rate[mask], accel[mask] = seg.evaluate(tau)
            rest_from = seg.rest_from_s
            origin = self._rest_origin_s[j]
            if rest_from is not None and origin is not None:
                at_rest = tau >= rest_from
                sub = np.full(tau.shape, np.inf)
                sub[at_rest] = np.maximum(t[mask][at_rest] - origin, 0.0)
                since_rest[mask] = sub
        return angle, rate, accel, since_rest


@dataclass(frozen=True)
class TableProfile:
    """All axes of a table, outermost first."""

    axes: tuple[AxisProfile, ...]

    def __post_init__(self) -> None:
        if not self.axes:
            raise ValueError("TableProfile: at least one axis is needed")
        object.__setattr__(self, "axes", tuple(self.axes))

    @property
    def n_axes(self) -> int:
        return len(self.axes)

    @property
    def end_s(self) -> float:
        """Time the last axis finishes its last segment (s)."""
        return max(a.end_s for a in self.axes)

    def kinematics(self, t_s: FloatArray) -> TableKinematics:
        """Evaluate every axis at ``t_s`` (n,) -> :class:`TableKinematics` with (n, k) arrays."""
        t = np.asarray(t_s, dtype=float).reshape(-1)
        cols = [a.evaluate(t) for a in self.axes]
        return TableKinematics(
            t_s=t,
            angles_rad=np.stack([c[0] for c in cols], axis=1),
            rates_rad_s=np.stack([c[1] for c in cols], axis=1),
            accels_rad_s2=np.stack([c[2] for c in cols], axis=1),
            since_rest_s=np.stack([c[3] for c in cols], axis=1),
        )

    __call__ = kinematics
