"""Motion pieces the simulated controller needs beyond ``drivers/sim/motion.py``.

All satisfy :class:`drivers.sim.motion.Segment` (vectorised ``evaluate(tau_s)`` returning
angle rad, rate rad/s, accel rad/s²) so they chain in an :class:`AxisProfile`:

* :class:`Truncated` cuts any segment short when the controller replans mid-motion;
* :class:`RingDown` is the servo's damped ringing about a target after a move;
* :class:`RampedOscillation` starts a sinusoid from rest with a raised-cosine amplitude
  envelope, as a table does, instead of a step in rate;
* :func:`plan_move` plans a point-to-point move from any (angle, rate) state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drivers.sim.motion import ConstantRate, Evaluation, FloatArray, Segment, TrapezoidMove


@dataclass(frozen=True)
class Truncated:
    """``inner`` cut to its first ``duration_s`` seconds (it extrapolates no further in a profile)."""

    inner: Segment
    duration_s: float

    @property
    def start_rad(self) -> float:
        return self.inner.start_rad

    @property
    def rest_from_s(self) -> float | None:
        rest = self.inner.rest_from_s
        return rest if rest is not None and rest <= self.duration_s else None

    def evaluate(self, tau_s: FloatArray) -> Evaluation:
        return self.inner.evaluate(tau_s)


@dataclass(frozen=True)
class RingDown:
    """Damped ringing about ``target_rad`` after a move.

    r(τ) = A0·Ωd·τ·e^(−τ/τd)·sin(Ωd·τ), θ = target + r. r(0) = r'(0) = 0, so the ring joins
    the end of a move (at rest) without a jump in angle or rate. Its envelope
    A0·Ωd·τ·e^(−τ/τd) peaks at τ = τd with the value ``peak_rad`` = A0·Ωd·τd/e.

    :param target_rad: angle the axis settles to (rad).
    :param peak_rad: largest excursion of the envelope (rad).
    :param frequency_hz: ringing frequency Ωd/2π (Hz).
    :param decay_s: envelope time constant τd (s).
    :param window_rad: position window; ``rest_from_s`` is when the envelope stays inside it.
    """

    target_rad: float
    peak_rad: float
    frequency_hz: float
    decay_s: float
    window_rad: float
    duration_s: float = 0.0

    @property
    def start_rad(self) -> float:
        return self.target_rad

    @property
    def rest_from_s(self) -> float | None:
        return self.settled_after_s()

    def envelope(self, tau_s: FloatArray) -> FloatArray:
        """|r(τ)| bound: peak·(τ/τd)·e^(1 − τ/τd) (rad)."""
        x = np.asarray(tau_s, dtype=float) / self.decay_s
        return self.peak_rad * x * np.exp(1.0 - x)

    def settled_after_s(self) -> float:
        """First τ after the envelope's peak where it falls below the window (0 if it never exceeds it)."""
        if self.peak_rad <= self.window_rad:
            return 0.0
        # Solve peak·x·e^(1−x) = window for x > 1 by bisection on [1, 1 + 60].
        lo, hi = 1.0, 61.0
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if self.peak_rad * mid * math.exp(1.0 - mid) > self.window_rad:
                lo = mid
            else:
                hi = mid
        return hi * self.decay_s

    def evaluate(self, tau_s: FloatArray) -> Evaluation:
        tau = np.asarray(tau_s, dtype=float)
        w = 2.0 * math.pi * self.frequency_hz
        sigma = 1.0 / self.decay_s
        a0 = self.peak_rad * math.e * sigma / w
        e = np.exp(-sigma * tau)
        u = a0 * w * tau * e
        du = a0 * w * e * (1.0 - sigma * tau)
        ddu = a0 * w * e * (sigma * sigma * tau - 2.0 * sigma)
        s, c = np.sin(w * tau), np.cos(w * tau)
        return self.target_rad + u * s, du * s + u * w * c, ddu * s + 2.0 * du * w * c - u * w * w * s


@dataclass(frozen=True)
class RampedOscillation:
    """θ = c + e(τ)·A·sin(Ωτ + φ), with e rising as ½(1 − cos(πτ/T_r)) over ``ramp_s``.

    Derivatives by the product rule: θ' = e'·A·s + e·A·Ω·cos, θ'' = e''·A·s + 2e'·A·Ω·cos −
    e·A·Ω²·s. After ``ramp_s`` (e = 1) it is a plain sinusoid and keeps oscillating.
    """

    centre_rad: float
    amplitude_rad: float
    period_s: float
    phase_rad: float
    ramp_s: float

    @property
    def duration_s(self) -> float:
        return self.ramp_s

    @property
    def start_rad(self) -> float:
        return self.centre_rad

    @property
    def rest_from_s(self) -> float | None:
        return None

    def evaluate(self, tau_s: FloatArray) -> Evaluation:
        tau = np.asarray(tau_s, dtype=float)
        w = 2.0 * math.pi / self.period_s
        k = math.pi / self.ramp_s
        ramp = tau < self.ramp_s
        e = np.where(ramp, 0.5 * (1.0 - np.cos(k * tau)), 1.0)
        de = np.where(ramp, 0.5 * k * np.sin(k * tau), 0.0)
        dde = np.where(ramp, 0.5 * k * k * np.cos(k * tau), 0.0)
        a = self.amplitude_rad
        s, c = np.sin(w * tau + self.phase_rad), np.cos(w * tau + self.phase_rad)
        return (
            self.centre_rad + e * a * s,
            de * a * s + e * a * w * c,
            dde * a * s + 2.0 * de * a * w * c - e * a * w * w * s,
        )


def plan_stop(angle_rad: float, rate_rad_s: float, accel_max_rad_s2: float) -> ConstantRate:
    """Decelerate from ``rate_rad_s`` to rest at ``accel_max_rad_s2``, then stand still."""
    ramp_s = abs(rate_rad_s) / accel_max_rad_s2
    return ConstantRate(angle_rad, 0.0, accel_max_rad_s2, ramp_s, initial_rate_rad_s=rate_rad_s)


def plan_move(
    angle_rad: float, rate_rad_s: float, target_rad: float, rate_max_rad_s: float, accel_max_rad_s2: float
) -> list[Segment]:
    """Segments taking an axis from (angle, rate) to rest at ``target_rad``.

    From rest: one trapezoid. While moving: first decelerate to rest (a controlled stop),
    then a trapezoid from where it stopped; simple and never exceeds the limits, at the
    cost of a longer path than a blended move.
    """
    segments: list[Segment] = []
    start = angle_rad
    if rate_rad_s != 0.0:
        stop = plan_stop(angle_rad, rate_rad_s, accel_max_rad_s2)
        segments.append(stop)
        start = float(stop.evaluate(np.array([stop.duration_s]))[0][0])
    segments.append(TrapezoidMove(start, target_rad, rate_max_rad_s, accel_max_rad_s2))
    return segments


def wrap_deg(angle_deg: float) -> float:
    """Angle wrapped to [−180, 180) deg."""
    return (angle_deg + 180.0) % 360.0 - 180.0
