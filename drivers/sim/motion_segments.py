"""Motion segments of one table axis: hold, trapezoidal move, constant rate, oscillation.

Each segment is pure and vectorised: ``evaluate(tau_s)`` gives ``(angle_rad, rate_rad_s,
accel_rad_s2)`` at times since the segment's start. Angles are the controller's own
(encoder) coordinates in radians. Beyond its duration a segment extrapolates physically:
a hold or a finished move stays where it ended, a constant rate keeps turning, an
oscillation keeps oscillating. :mod:`drivers.sim.motion` chains segments into profiles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

FloatArray = npt.NDArray[np.float64]
Evaluation = tuple[FloatArray, FloatArray, FloatArray]
"""(angle_rad, rate_rad_s, accel_rad_s2), each shaped like the time argument."""


class Segment(Protocol):
    """One piece of an axis's motion."""

    @property
    def start_rad(self) -> float:
        """Angle at the segment's start (rad)."""
        ...

    @property
    def duration_s(self) -> float:
        """Length of the segment (s)."""
        ...

    @property
    def rest_from_s(self) -> float | None:
        """Time into the segment from which the axis is at rest, ``None`` if it never is."""
        ...

    def evaluate(self, tau_s: FloatArray) -> Evaluation:
        """State at times ``tau_s`` (s since the segment's start, ≥ 0)."""
        ...


@dataclass(frozen=True)
class Hold:
    """The axis stands still at ``angle_rad`` for ``duration_s``."""

    angle_rad: float
    duration_s: float

    def __post_init__(self) -> None:
        _check_finite(self)
        if self.duration_s < 0:
            raise ValueError(f"Hold: duration_s must be >= 0, got {self.duration_s}")

    @property
    def start_rad(self) -> float:
        return self.angle_rad

    @property
    def rest_from_s(self) -> float | None:
        return 0.0

    def evaluate(self, tau_s: FloatArray) -> Evaluation:
        tau = np.asarray(tau_s, dtype=float)
        zero = np.zeros_like(tau)
        return zero + self.angle_rad, zero, zero.copy()


@dataclass(frozen=True)
class TrapezoidMove:
    """Point-to-point move with a trapezoidal rate profile, from rest to rest.

    Accelerates at ``accel_max_rad_s2`` to ``rate_max_rad_s``, cruises, decelerates. When
    the distance D is shorter than rate_max²/accel_max the profile is triangular with peak
    rate √(D·accel_max). Duration: 2·v/a + (D − v²/a)/v (trapezoid) or 2·√(D/a) (triangle).
    """

    start_angle_rad: float
    end_rad: float
    rate_max_rad_s: float
    accel_max_rad_s2: float

    def __post_init__(self) -> None:
        _check_finite(self)
        if self.rate_max_rad_s <= 0 or self.accel_max_rad_s2 <= 0:
            raise ValueError(
                "TrapezoidMove: rate_max_rad_s and accel_max_rad_s2 must be > 0, got "
                f"{self.rate_max_rad_s}, {self.accel_max_rad_s2}"
            )

    @property
    def start_rad(self) -> float:
        return self.start_angle_rad

    @property
    def _phases(self) -> tuple[float, float, float]:
        """(peak rate rad/s, accelerating time s, cruising time s)."""
        distance = abs(self.end_rad - self.start_angle_rad)
        v, a = self.rate_max_rad_s, self.accel_max_rad_s2
        if distance >= v * v / a:
            return v, v / a, (distance - v * v / a) / v
        peak = math.sqrt(distance * a)
        return peak, peak / a, 0.0

    @property
    def duration_s(self) -> float:
        _, t_acc, t_cruise = self._phases
        return 2.0 * t_acc + t_cruise

    @property
    def rest_from_s(self) -> float | None:
        return self.duration_s

    def evaluate(self, tau_s: FloatArray) -> Evaluation:
        tau = np.asarray(tau_s, dtype=float)
        peak, t_acc, t_cruise = self._phases
        a = self.accel_max_rad_s2
        sign = 1.0 if self.end_rad >= self.start_angle_rad else -1.0
        t_dec = t_acc + t_cruise
        t_end = t_dec + t_acc
        d_acc = 0.5 * a * t_acc * t_acc
        d_cruise = peak * t_cruise
        ramp_up = tau < t_acc
        cruise = (tau >= t_acc) & (tau < t_dec)
        ramp_down = (tau >= t_dec) & (tau < t_end)
        u = tau - t_dec
        dist = np.select(
            [ramp_up, cruise, ramp_down],
            [
                0.5 * a * tau * tau,
                d_acc + peak * (tau - t_acc),
                d_acc + d_cruise + peak * u - 0.5 * a * u * u,
            ],
            default=2.0 * d_acc + d_cruise,
        )
        rate = np.select([ramp_up, cruise, ramp_down], [a * tau, np.full_like(tau, peak), peak - a * u], 0.0)
        accel = np.select([ramp_up, ramp_down], [np.full_like(tau, a), np.full_like(tau, -a)], 0.0)
        return self.start_angle_rad + sign * dist, sign * rate, sign * accel


@dataclass(frozen=True)
class ConstantRate:
    """Ramp from ``initial_rate_rad_s`` to ``rate_rad_s`` at ``accel_max_rad_s2``, then hold that rate.

    The ramp lasts |rate − initial_rate| / accel_max; ``duration_s`` (the whole segment)
    must be at least that. With ``rate_rad_s = 0`` this is a controlled stop.
    """

    start_angle_rad: float
    rate_rad_s: float
    accel_max_rad_s2: float
    duration_s: float
    initial_rate_rad_s: float = 0.0

    def __post_init__(self) -> None:
        _check_finite(self)
        if self.accel_max_rad_s2 <= 0:
            raise ValueError(f"ConstantRate: accel_max_rad_s2 must be > 0, got {self.accel_max_rad_s2}")
        if self.duration_s < self.ramp_s * (1.0 - 1e-12):
            raise ValueError(
                f"ConstantRate: duration_s={self.duration_s} is shorter than the ramp ({self.ramp_s:.6g} s)"
            )

    @property
    def start_rad(self) -> float:
        return self.start_angle_rad

    @property
    def ramp_s(self) -> float:
        """Length of the rate ramp (s)."""
        return abs(self.rate_rad_s - self.initial_rate_rad_s) / self.accel_max_rad_s2

    @property
    def rest_from_s(self) -> float | None:
        return self.ramp_s if self.rate_rad_s == 0.0 else None

    def evaluate(self, tau_s: FloatArray) -> Evaluation:
        tau = np.asarray(tau_s, dtype=float)
        w0, w1, t_r = self.initial_rate_rad_s, self.rate_rad_s, self.ramp_s
        a = math.copysign(self.accel_max_rad_s2, w1 - w0) if t_r > 0 else 0.0
        ramp = tau < t_r
        tr = np.minimum(tau, t_r)
        angle = self.start_angle_rad + w0 * tr + 0.5 * a * tr * tr + w1 * (tau - tr)
        rate = np.where(ramp, w0 + a * tau, w1)
        accel = np.where(ramp, a, 0.0)
        return angle, rate, accel


@dataclass(frozen=True)
class Oscillation:
    """Sinusoidal oscillation θ = c + A·sin(2π·τ/T + φ) for ``duration_s``.

    Rate A·Ω·cos(Ωτ + φ), acceleration −A·Ω²·sin(Ωτ + φ), Ω = 2π/T.
    """

    centre_rad: float
    amplitude_rad: float
    period_s: float
    duration_s: float
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        _check_finite(self)
        if self.period_s <= 0 or self.duration_s < 0:
            raise ValueError(
                "Oscillation: period_s must be > 0 and duration_s >= 0, got "
                f"{self.period_s}, {self.duration_s}"
            )

    @property
    def start_rad(self) -> float:
        return self.centre_rad + self.amplitude_rad * math.sin(self.phase_rad)

    @property
    def rest_from_s(self) -> float | None:
        return None

    def evaluate(self, tau_s: FloatArray) -> Evaluation:
        tau = np.asarray(tau_s, dtype=float)
        omega = 2.0 * math.pi / self.period_s
        arg = omega * tau + self.phase_rad
        s = np.sin(arg)
        return (
            self.centre_rad + self.amplitude_rad * s,
            self.amplitude_rad * omega * np.cos(arg),
            -self.amplitude_rad * omega * omega * s,
        )


def end_state(segment: Segment) -> tuple[float, float]:
    """(angle_rad, rate_rad_s) at the end of ``segment``."""
    angle, rate, _ = segment.evaluate(np.array([segment.duration_s]))
    return float(angle[0]), float(rate[0])


def _check_finite(segment: DataclassInstance) -> None:
    """Every dataclass field of ``segment`` is a finite number."""
    for f in fields(segment):
        value = getattr(segment, f.name)
        if not math.isfinite(value):
            raise ValueError(f"{type(segment).__name__}: {f.name} must be finite, got {value!r}")
