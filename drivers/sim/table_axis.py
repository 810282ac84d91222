"""One simulated table axis: its motion history, demands, and servo state.

Time is passed in (simulated seconds); nothing here reads a clock or locks. The axis keeps
its motion as a chain of segments (an :class:`AxisProfile`); every new demand cuts the
running segment at the demand time and appends the new plan, so the history is exact and
can be evaluated at any retained time, vectorised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drivers.base import AxisMode
from drivers.sim.motion import AxisProfile, ConstantRate, Hold, Oscillation, Segment
from drivers.sim.table_segments import RampedOscillation, RingDown, Truncated, plan_move, plan_stop, wrap_deg


@dataclass(frozen=True)
class AxisLimits:
    """Limits and servo tolerances of one axis.

    :param rate_deg_s: absolute rate limit (deg/s); per-mode limits may be lower.
    :param acc_deg_s2: absolute acceleration limit (deg/s²).
    :param pos_lo_deg: lower software position limit (deg); −180 with +180 = unlimited travel.
    :param pos_hi_deg: upper software position limit (deg).
    :param window_deg: in-position window (deg).
    :param settle_s: time the position must stay in the window before in-position is set (s).
    :param rate_tol_deg_s: at-rate tolerance (deg/s).
    """

    rate_deg_s: float = 200.0
    acc_deg_s2: float = 200.0
    pos_lo_deg: float = -180.0
    pos_hi_deg: float = 180.0
    window_deg: float = 0.001
    settle_s: float = 0.5
    rate_tol_deg_s: float = 0.01

    def __post_init__(self) -> None:
        for name in ("rate_deg_s", "acc_deg_s2", "window_deg", "rate_tol_deg_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"AxisLimits: {name} must be finite and > 0, got {value!r}")
        if not (math.isfinite(self.settle_s) and self.settle_s >= 0):
            raise ValueError(f"AxisLimits: settle_s must be finite and >= 0, got {self.settle_s!r}")
        if not (-180.0 <= self.pos_lo_deg < self.pos_hi_deg <= 180.0):
            raise ValueError(
                f"AxisLimits: need -180 <= pos_lo_deg < pos_hi_deg <= 180, got "
                f"{self.pos_lo_deg!r}, {self.pos_hi_deg!r}"
            )

    @property
    def continuous(self) -> bool:
        """Unlimited travel (slip rings): moves take the shorter way round."""
        return self.pos_lo_deg <= -180.0 and self.pos_hi_deg >= 180.0

    @property
    def vtrip_deg_s(self) -> float:
        """Overspeed trip rate (deg/s): 10 % above the absolute rate limit."""
        return 1.1 * self.rate_deg_s


@dataclass(frozen=True)
class Ringing:
    """Damped ringing after every move (see :class:`RingDown`): peak (deg), frequency (Hz), decay (s)."""

    peak_deg: float
    frequency_hz: float
    decay_s: float

    def __post_init__(self) -> None:
        for name in ("peak_deg", "frequency_hz", "decay_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"Ringing: {name} must be finite and > 0, got {value!r}")


OSC_RAMP_PERIODS = 2.0
"""An oscillation demand ramps its amplitude in over this many periods."""


class SimAxis:
    """State of one axis. ``t`` arguments are simulated seconds, non-decreasing across calls."""

    def __init__(self, limits: AxisLimits, t0_s: float, angle_deg: float = 0.0) -> None:
        self.limits = limits
        self.mode = AxisMode.OFF
        self.mode_limits: dict[AxisMode, tuple[float, float]] = {
            m: (limits.rate_deg_s, limits.acc_deg_s2) for m in AxisMode if m is not AxisMode.OFF
        }
        self._starts: list[float] = [t0_s]
        self._segments: list[Segment] = [Hold(math.radians(angle_deg), 0.0)]
        self.motion_end_s = t0_s
        self.in_position_from_s = t0_s
        self.at_rate_from_s = t0_s
        self.rate_demand_deg_s = 0.0
        self.demand_deg = wrap_deg(angle_deg)
        self.stalled = False
        self.following_error = False

    # ---- history ---------------------------------------------------------------------
    def profile(self) -> AxisProfile:
        return AxisProfile(tuple(self._segments), self._starts[0])

    @property
    def oldest_s(self) -> float:
        return self._starts[0]

    def state(self, t: float) -> tuple[float, float, float]:
        """(angle rad unwrapped, rate rad/s, accel rad/s²) at ``t``."""
        angle, rate, accel, _ = self.profile().evaluate(np.array([t]))
        return float(angle[0]), float(rate[0]), float(accel[0])

    def _replan(self, t: float, segments: list[Segment]) -> None:
        """Drop what was planned after ``t``, cut the running segment at ``t``, append ``segments``."""
        while len(self._segments) > 1 and self._starts[-1] >= t:
            self._segments.pop()
            self._starts.pop()
        elapsed = max(t - self._starts[-1], 0.0)
        self._segments[-1] = Truncated(self._segments[-1], elapsed)
        start = self._starts[-1] + elapsed
        for seg in segments:
            self._starts.append(start)
            self._segments.append(seg)
            start += seg.duration_s

    def trim(self, before_s: float) -> None:
        """Forget segments that ended before ``before_s`` (always keeps the running one)."""
        while len(self._segments) > 1 and self._starts[1] <= before_s:
            self._starts.pop(0)
            self._segments.pop(0)

    # ---- motion ----------------------------------------------------------------------
    def moving(self, t: float) -> bool:
        return t < self.motion_end_s

    def brake(self, t: float, acc_deg_s2: float | None = None) -> None:
        """Decelerate to rest from the state at ``t`` and hold there."""
        angle, rate, _ = self.state(t)
        acc = math.radians(acc_deg_s2 if acc_deg_s2 is not None else self.limits.acc_deg_s2)
        if rate == 0.0 and not self.moving(t):
            self._replan(t, [Hold(angle, 0.0)])
            self.motion_end_s = min(self.motion_end_s, t)
        else:
            stop = plan_stop(angle, rate, acc)
            self._replan(t, [stop])
            self.motion_end_s = t + stop.duration_s
        end_angle = self.state(self.motion_end_s)[0]
        self.demand_deg = wrap_deg(math.degrees(end_angle))
        self.rate_demand_deg_s = 0.0
        self.in_position_from_s = self.motion_end_s + self.limits.settle_s
        self.at_rate_from_s = self.motion_end_s

    def hold_here(self, t: float) -> None:
        """Stop dead at the angle of ``t`` (a jammed axis)."""
        angle, _, _ = self.state(t)
        self._replan(t, [Hold(angle, 0.0)])
        self.motion_end_s = t

    def move_to(self, t: float, demand_deg: float, ringing: Ringing | None) -> float:
        """Plan a move to ``demand_deg`` (−180…180); returns the planned motion time (s)."""
        angle, rate, _ = self.state(t)
        if self.limits.continuous:
            target = angle + math.radians(wrap_deg(demand_deg - math.degrees(angle)))
        else:
            target = math.radians(demand_deg)
        rate_max, acc_max = self.mode_limits[AxisMode.POSITION]
        segments = plan_move(angle, rate, target, math.radians(rate_max), math.radians(acc_max))
        window = math.radians(self.limits.window_deg)
        motion_s = sum(s.duration_s for s in segments)
        settle_extra_s = 0.0
        if ringing is not None:
            ring = RingDown(
                target, math.radians(ringing.peak_deg), ringing.frequency_hz, ringing.decay_s, window
            )
            segments.append(ring)
            settle_extra_s = ring.settled_after_s()
        else:
            segments.append(Hold(target, 0.0))
        self.demand_deg = wrap_deg(demand_deg)
        if self.stalled:
            self.hold_here(t)
        else:
            self._replan(t, segments)
            self.motion_end_s = t + motion_s
        self.in_position_from_s = t + motion_s + settle_extra_s + self.limits.settle_s
        return motion_s

    def start_rate(self, t: float, rate_deg_s: float) -> None:
        angle, rate, _ = self.state(t)
        _, acc_max = self.mode_limits[AxisMode.RATE]
        rate_rad_s, acc_rad_s2 = math.radians(rate_deg_s), math.radians(acc_max)
        ramp_s = abs(rate_rad_s - rate) / acc_rad_s2
        seg = ConstantRate(angle, rate_rad_s, acc_rad_s2, ramp_s, initial_rate_rad_s=rate)
        self.rate_demand_deg_s = rate_deg_s
        self.at_rate_from_s = t + seg.ramp_s
        if self.stalled:
            self.hold_here(t)
            return
        self._replan(t, [seg])
        self.motion_end_s = math.inf if rate_deg_s != 0.0 else t + seg.ramp_s

    def start_oscillation(
        self, t: float, amplitude_deg: float, frequency_hz: float, phase_deg: float
    ) -> None:
        """Oscillate about the angle where the axis comes to rest (ramped in, see RampedOscillation)."""
        angle, rate, _ = self.state(t)
        _, acc_max = self.mode_limits[AxisMode.OSCILLATION]
        segments: list[Segment] = []
        start = t
        if rate != 0.0 or self.moving(t):
            stop = plan_stop(angle, rate, math.radians(acc_max))
            segments.append(stop)
            start += stop.duration_s
            angle = float(stop.evaluate(np.array([stop.duration_s]))[0][0])
        if amplitude_deg == 0.0:
            segments.append(Hold(angle, 0.0))
            self.motion_end_s = start
        else:
            period = 1.0 / frequency_hz
            amp, phase = math.radians(amplitude_deg), math.radians(phase_deg)
            ramp = RampedOscillation(angle, amp, period, phase, OSC_RAMP_PERIODS * period)
            phase_after = phase + 2.0 * math.pi * OSC_RAMP_PERIODS
            segments += [ramp, Oscillation(angle, amp, period, 0.0, phase_after)]
            self.motion_end_s = math.inf
        if self.stalled:
            self.hold_here(t)
            return
        self._replan(t, segments)

    # ---- readouts --------------------------------------------------------------------
    def in_position(self, t: float) -> bool:
        return (
            self.mode is AxisMode.POSITION
            and not self.stalled
            and not self.following_error
            and t >= self.in_position_from_s
        )

    def at_rate(self, t: float) -> bool:
        return self.mode is AxisMode.RATE and not self.stalled and t >= self.at_rate_from_s
