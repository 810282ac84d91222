"""Simulated three-axis table controller: the state machine behind the text protocol.

Protocol-agnostic: :mod:`drivers.sim.table_server` turns command lines into calls here.
Axes are numbered as in ``drivers.base`` (1 = outermost); the server maps wire numbers.
Time comes from a :class:`~drivers.sim.clock.SimClock`; the controller is lazy — every
call first applies what happened since the last one (scheduled faults), so no thread runs.

Behaviour (see ``docs/table-protocol.md``): trapezoidal moves at the position-mode rate
and acceleration limits, in-position after the window held for ``settle_s``; rate mode
ramps at the acceleration limit; synthesis (oscillation) ramps its amplitude in over two
periods; changing mode while moving is refused; motion needs a closed interlock; STOP
decelerates and stays in mode; E-stop and interlock faults brake every axis at the
absolute acceleration limit. Rejected commands raise :class:`Rejected` and are queued in
the SCPI error queue (10 entries, the last replaced by −350 on overflow).

Injectable faults (:meth:`TableController.inject`): ``no_reply``, ``garbled``
(``probability``), ``stalled_axis`` (``axis``, ``trip_s``), ``interlock_trip``
(``after_s``), ``slow_settle`` (``peak_deg``, ``frequency_hz``, ``decay_s``).
"""

from __future__ import annotations

import math

import numpy as np

from drivers.base import AxisMode
from drivers.sim.motion import TableKinematics
from drivers.sim.table_axis import AxisLimits, Ringing
from drivers.sim.table_core import HISTORY_S, ControllerCore
from drivers.sim.table_errors import QueuedError, Rejected
from drivers.sim.table_segments import wrap_deg
from drivers.table_protocol import AxisErrorCode, Interlock, ScpiError, Status

__all__ = ["HISTORY_S", "IDENTITY", "AxisLimits", "QueuedError", "Rejected", "Ringing", "TableController"]

IDENTITY = "SIMTABLE,3AX-100,SN0001,FW2.3"


class TableController(ControllerCore):
    """The simulated controller. Thread-safe (one re-entrant lock around every call).

    Construct as :class:`ControllerCore`: ``TableController(clock, n_axes=3, limits=..., seed=...)``.
    """

    # ---- system ------------------------------------------------------------------------
    def identity(self) -> str:
        return IDENTITY

    def reset(self) -> None:
        """``*RST``: brake every axis, modes OFF, interlocks open, axis faults cleared (E-stop stays)."""
        with self._lock:
            t = self._now()
            for i, ax in enumerate(self._axes):
                ax.brake(t)
                ax.mode = AxisMode.OFF
                ax.following_error = False
                self._interlock[i] = Interlock.OPEN

    def estop(self) -> None:
        with self._lock:
            t = self._now()
            self._estop = True
            for i, ax in enumerate(self._axes):
                ax.brake(t)
                ax.mode = AxisMode.OFF
                self._interlock[i] = Interlock.OPEN

    def estop_reset(self) -> None:
        with self._lock:
            self._now()
            self._estop = False

    # ---- interlocks ----------------------------------------------------------------------
    def interlock_close(self, axis: int | None) -> None:
        with self._lock:
            self._now()
            for a in self._axes_of(axis):
                if self._estop:
                    raise self.reject(ScpiError.SETTINGS_CONFLICT, "Settings conflict: E-stop latched")
                if self._interlock[a - 1] is Interlock.FAULT:
                    raise self.reject(
                        ScpiError.SETTINGS_CONFLICT, "Settings conflict: interlock fault, reset first"
                    )
                self._interlock[a - 1] = Interlock.CLOSED

    def interlock_open(self, axis: int | None) -> None:
        with self._lock:
            t = self._now()
            for a in self._axes_of(axis):
                ax = self._axes[a - 1]
                ax.brake(t)
                ax.mode = AxisMode.OFF
                if self._interlock[a - 1] is Interlock.CLOSED:
                    self._interlock[a - 1] = Interlock.OPEN

    def interlock_reset(self, axis: int | None) -> None:
        """Clear an interlock fault (to Open) and the axis's latched faults."""
        with self._lock:
            self._now()
            for a in self._axes_of(axis):
                if self._interlock[a - 1] is Interlock.FAULT:
                    self._interlock[a - 1] = Interlock.OPEN
                self._axes[a - 1].following_error = False

    def interlock_state(self, axis: int) -> Interlock:
        with self._lock:
            self._now()
            self._axis(axis)
            return self._interlock[axis - 1]

    # ---- modes and demands -----------------------------------------------------------
    def set_mode(self, axis: int | None, mode: AxisMode) -> None:
        with self._lock:
            t = self._now()
            for a in self._axes_of(axis):
                ax = self._axes[a - 1]
                if mode is AxisMode.OFF:
                    ax.brake(t)
                    ax.mode = AxisMode.OFF
                    continue
                self._require_servo(a, None)
                if ax.mode is mode:
                    continue
                if ax.moving(t):
                    raise self.reject(ScpiError.SETTINGS_CONFLICT, "Settings conflict: axis moving")
                if mode is AxisMode.RATE and not ax.limits.continuous:
                    raise self.reject(ScpiError.SETTINGS_CONFLICT, "Settings conflict: limited-travel axis")
                ax.brake(t)
                ax.in_position_from_s = t
                ax.mode = mode

    def mode(self, axis: int) -> AxisMode:
        with self._lock:
            self._now()
            return self._axis(axis).mode

    def demand_position(self, axis: int, angle_deg: float) -> None:
        with self._lock:
            t = self._now()
            self._require_finite(angle_deg=angle_deg)
            ax = self._require_servo(axis, AxisMode.POSITION)
            if not -180.0 <= angle_deg <= 180.0:
                raise self.reject(
                    ScpiError.DATA_OUT_OF_RANGE, "Data out of range: position outside -180..180"
                )
            if angle_deg > ax.limits.pos_hi_deg:
                raise self.reject(AxisErrorCode.SOFTWARE_LIMIT_PLUS, "Software limit +", axis)
            if angle_deg < ax.limits.pos_lo_deg:
                raise self.reject(AxisErrorCode.SOFTWARE_LIMIT_MINUS, "Software limit -", axis)
            motion_s = ax.move_to(t, angle_deg, self.ringing)
            if ax.stalled:
                self._schedule_stall_trip(axis, t + motion_s)

    def demand_delta(self, axis: int, delta_deg: float) -> None:
        with self._lock:
            self._now()
            self._require_finite(delta_deg=delta_deg)
            ax = self._require_servo(axis, AxisMode.POSITION)
            if abs(delta_deg) > 180.0:
                raise self.reject(ScpiError.DATA_OUT_OF_RANGE, "Data out of range: |delta| > 180")
            target = ax.demand_deg + delta_deg
            self.demand_position(axis, wrap_deg(target) if ax.limits.continuous else target)

    def demand_rate(self, axis: int, rate_deg_s: float) -> None:
        with self._lock:
            t = self._now()
            self._require_finite(rate_deg_s=rate_deg_s)
            ax = self._require_servo(axis, AxisMode.RATE)
            if abs(rate_deg_s) > ax.mode_limits[AxisMode.RATE][0]:
                raise self.reject(ScpiError.DATA_OUT_OF_RANGE, "Data out of range: rate above limit")
            ax.start_rate(t, rate_deg_s)
            if ax.stalled and rate_deg_s != 0.0:
                self._schedule_stall_trip(axis, t)

    def demand_oscillation(
        self, axis: int, amplitude_deg: float, frequency_hz: float, phase_deg: float
    ) -> None:
        with self._lock:
            t = self._now()
            self._require_finite(amplitude_deg=amplitude_deg, frequency_hz=frequency_hz, phase_deg=phase_deg)
            ax = self._require_servo(axis, AxisMode.OSCILLATION)
            rate_max, acc_max = ax.mode_limits[AxisMode.OSCILLATION]
            omega = 2.0 * math.pi * frequency_hz
            if (
                amplitude_deg < 0
                or frequency_hz <= 0
                or amplitude_deg * omega > rate_max
                or amplitude_deg * omega * omega > acc_max
            ):
                raise self.reject(ScpiError.DATA_OUT_OF_RANGE, "Data out of range: oscillation beyond limits")
            centre = math.degrees(ax.state(t)[0])
            if not ax.limits.continuous and (
                centre + amplitude_deg > ax.limits.pos_hi_deg or centre - amplitude_deg < ax.limits.pos_lo_deg
            ):
                raise self.reject(AxisErrorCode.SOFTWARE_LIMIT_PLUS, "Software limit", axis)
            ax.start_oscillation(t, amplitude_deg, frequency_hz, phase_deg)
            if ax.stalled and amplitude_deg > 0:
                self._schedule_stall_trip(axis, t)

    def stop(self, axis: int | None) -> None:
        """Decelerate at the mode's acceleration limit to rest; the mode stays."""
        with self._lock:
            t = self._now()
            for a in self._axes_of(axis):
                ax = self._axes[a - 1]
                acc = ax.mode_limits[ax.mode][1] if ax.mode in ax.mode_limits else ax.limits.acc_deg_s2
                ax.brake(t, acc)

    # ---- limits ------------------------------------------------------------------------
    def set_limit(self, kind: str, mode: AxisMode, axis: int, value: float) -> None:
        """Per-mode ``rate`` (deg/s) or ``acc`` (deg/s²) limit, at most the absolute limit."""
        with self._lock:
            self._now()
            ax = self._axis(axis)
            self._require_finite(value=value)
            if mode is AxisMode.OFF:
                raise self.reject(ScpiError.DATA_OUT_OF_RANGE, "Data out of range: no limits in mode OFF")
            absolute = ax.limits.rate_deg_s if kind == "rate" else ax.limits.acc_deg_s2
            if not 0 < value <= absolute:
                raise self.reject(ScpiError.DATA_OUT_OF_RANGE, f"Data out of range: {kind} limit")
            rate, acc = ax.mode_limits[mode]
            ax.mode_limits[mode] = (value, acc) if kind == "rate" else (rate, value)

    def absolute_limits(self, axis: int) -> AxisLimits:
        with self._lock:
            return self._axis(axis).limits

    # ---- readouts --------------------------------------------------------------------
    def read(self, axis: int) -> tuple[float, float, float]:
        """(position deg wrapped to [−180, 180), rate deg/s, acceleration deg/s²) now."""
        with self._lock:
            t = self._now()
            angle, rate, acc = self._axis(axis).state(t)
            return wrap_deg(math.degrees(angle)), math.degrees(rate), math.degrees(acc)

    def status(self, axis: int) -> Status:
        with self._lock:
            t = self._now()
            ax = self._axis(axis)
            s = Status(0)
            if ax.in_position(t):
                s |= Status.IN_POSITION
            if ax.moving(t):
                s |= Status.MOVING
            if ax.at_rate(t):
                s |= Status.AT_RATE
            if self._interlock[axis - 1] is Interlock.CLOSED:
                s |= Status.INTERLOCK_CLOSED
            if self._estop:
                s |= Status.ESTOP
            if ax.following_error:
                s |= Status.FOLLOWING_ERROR
            return s

    def kinematics(self, t_s: np.ndarray) -> TableKinematics:
        """TRUE state of every axis at simulated times ``t_s`` (n,), axes outermost first.

        Angles are unwrapped (rad). Times may be anything from the oldest retained history
        (``history_s`` before now) on; times after now give the motion as planned now.

        :raises ValueError: a time older than the retained history, or not finite.
        """
        t = np.asarray(t_s, dtype=float).reshape(-1)
        with self._lock:
            self._now()
            if t.size and not np.all(np.isfinite(t)):
                raise ValueError("kinematics: times must be finite")
            oldest = max(ax.oldest_s for ax in self._axes)
            if t.size and float(t.min()) < oldest - 1e-9:
                raise ValueError(
                    f"kinematics: t={float(t.min()):.6g} s is older than the retained "
                    f"history (oldest {oldest:.6g} s)"
                )
            cols = [ax.profile().evaluate(t) for ax in self._axes]
        return TableKinematics(
            t_s=t,
            angles_rad=np.stack([c[0] for c in cols], axis=1),
            rates_rad_s=np.stack([c[1] for c in cols], axis=1),
            accels_rad_s2=np.stack([c[2] for c in cols], axis=1),
            since_rest_s=np.stack([c[3] for c in cols], axis=1),
        )
