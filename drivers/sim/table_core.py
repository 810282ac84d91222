"""State and plumbing of the simulated table controller: axes, clock, events, faults.

:class:`ControllerCore` holds what every command needs (the axes, interlocks, the error
queue, scheduled events, injected faults); :class:`~drivers.sim.table_controller.TableController`
adds the commands. The controller is lazy: every call first applies the events that fell
due since the last call (:meth:`ControllerCore._now`), so no thread runs.
"""

from __future__ import annotations

import functools
import heapq
import math
import random
import threading
from collections.abc import Callable, Sequence
from typing import Any

from drivers.base import AxisMode
from drivers.sim.clock import SimClock
from drivers.sim.table_axis import AxisLimits, Ringing, SimAxis
from drivers.sim.table_errors import ErrorQueue, QueuedError, Rejected
from drivers.sim.table_faults import FAULTS, check_fault_params
from drivers.table_protocol import AxisErrorCode, Interlock, ScpiError

HISTORY_S = 60.0


class ControllerCore:
    """The simulated controller. Thread-safe (one re-entrant lock around every call).

    :param clock: the simulated clock.
    :param n_axes: number of axes (outermost first).
    :param limits: one :class:`AxisLimits` for all axes, or one per axis.
    :param seed: seed of the random generator used for garbled replies.
    :param ringing: ringing after every move (``None``: a clean servo).
    :param history_s: how far back :meth:`kinematics` can look (simulated s).
    :param initial_deg: starting angles, outermost first (deg).
    """

    def __init__(
        self,
        clock: SimClock,
        n_axes: int = 3,
        limits: AxisLimits | Sequence[AxisLimits] | None = None,
        seed: int = 0,
        *,
        ringing: Ringing | None = None,
        history_s: float = HISTORY_S,
        initial_deg: Sequence[float] | None = None,
    ) -> None:
        if n_axes < 1 or n_axes > 9:
            raise ValueError(f"n_axes must be 1..9, got {n_axes}")
        per_axis = [limits or AxisLimits()] * n_axes if not isinstance(limits, Sequence) else list(limits)
        if len(per_axis) != n_axes:
            raise ValueError(f"limits: expected {n_axes} AxisLimits, got {len(per_axis)}")
        start = list(initial_deg) if initial_deg is not None else [0.0] * n_axes
        if len(start) != n_axes or not all(math.isfinite(a) for a in start):
            raise ValueError(f"initial_deg: expected {n_axes} finite angles, got {initial_deg!r}")
        self.clock = clock
        self.n_axes = n_axes
        self.history_s = history_s
        self.rng = random.Random(seed)
        self._lock = threading.RLock()
        t0 = clock.now_s()
        self._axes = [SimAxis(lim, t0, a) for lim, a in zip(per_axis, start, strict=True)]
        self._interlock = [Interlock.OPEN] * n_axes
        self._estop = False
        self._queue = ErrorQueue()
        self._events: list[tuple[float, int, Callable[[float], None]]] = []
        self._event_seq = 0
        self._base_ringing = ringing
        self._faults: dict[str, dict[str, Any]] = {}

    # ---- infrastructure ----------------------------------------------------------------
    def _now(self) -> float:
        """Apply due events, trim history, and return the current simulated time."""
        now = self.clock.now_s()
        while self._events and self._events[0][0] <= now:
            t_event, _, action = heapq.heappop(self._events)
            action(t_event)
        for ax in self._axes:
            ax.trim(now - self.history_s)
        return now

    def _schedule(self, t: float, action: Callable[[float], None]) -> None:
        self._event_seq += 1
        heapq.heappush(self._events, (t, self._event_seq, action))

    def _push(self, entry: QueuedError) -> None:
        self._queue.push(entry)

    def reject(self, code: int, text: str, axis: int | None = None) -> Rejected:
        """Queue an error and return the exception to raise."""
        self._push(QueuedError(code, text, axis))
        return Rejected(code, text, axis)

    def push_error(self, code: int, text: str) -> None:
        """Queue an error found outside the controller (a syntax error seen by the server)."""
        with self._lock:
            self._push(QueuedError(code, text))

    def pop_error(self) -> QueuedError | None:
        """Oldest queued error, ``None`` when the queue is empty."""
        with self._lock:
            self._now()
            return self._queue.pop()

    def _axis(self, axis: int) -> SimAxis:
        if not isinstance(axis, int) or not 1 <= axis <= self.n_axes:
            raise self.reject(ScpiError.DATA_OUT_OF_RANGE, f"Data out of range: axis {axis!r}")
        return self._axes[axis - 1]

    def _axes_of(self, axis: int | None) -> list[int]:
        if axis is None:
            return list(range(1, self.n_axes + 1))
        self._axis(axis)
        return [axis]

    def _require_finite(self, **values: float) -> None:
        for name, v in values.items():
            if not math.isfinite(v):
                raise self.reject(ScpiError.DATA_OUT_OF_RANGE, f"Data out of range: {name} {v!r}")

    def _require_servo(self, axis: int, mode: AxisMode | None) -> SimAxis:
        ax = self._axis(axis)
        if self._estop:
            raise self.reject(AxisErrorCode.ESTOP, "E-stop latched", axis)
        if self._interlock[axis - 1] is not Interlock.CLOSED:
            raise self.reject(
                AxisErrorCode.INTERLOCK, f"Interlock {self._interlock[axis - 1].value.lower()}", axis
            )
        if mode is not None and ax.mode is not mode:
            raise self.reject(ScpiError.SETTINGS_CONFLICT, f"Settings conflict: axis not in {mode.name} mode")
        return ax

    @property
    def ringing(self) -> Ringing | None:
        p = self._faults.get("slow_settle")
        return (
            Ringing(p["peak_deg"], p["frequency_hz"], p["decay_s"]) if p is not None else self._base_ringing
        )

    # ---- faults ------------------------------------------------------------------------
    def inject(self, fault: str, **params: Any) -> None:
        """Turn a fault on (see the module docstring for names and parameters)."""
        with self._lock:
            t = self._now()
            full = check_fault_params(fault, params, self.n_axes)
            self._faults[fault] = full
            if fault == "stalled_axis":
                ax = self._axes[full["axis"] - 1]
                was_moving = ax.moving(t)
                ax.stalled = True
                ax.hold_here(t)
                if was_moving:
                    self._schedule_stall_trip(full["axis"], t)
            elif fault == "interlock_trip":
                self._schedule(t + full["after_s"], self._trip_interlocks)

    def clear(self, fault: str) -> None:
        """Turn a fault off. Latched effects (an interlock fault, a following error) stay until reset."""
        if fault not in FAULTS:
            raise ValueError(f"unknown fault {fault!r}; known: {sorted(FAULTS)}")
        with self._lock:
            params = self._faults.pop(fault, None)
            if fault == "stalled_axis" and params is not None:
                self._axes[params["axis"] - 1].stalled = False

    def fault(self, fault: str) -> dict[str, Any] | None:
        """Parameters of an active fault, ``None`` when it is off."""
        with self._lock:
            return self._faults.get(fault)

    def _schedule_stall_trip(self, axis: int, t_motion_end: float) -> None:
        trip_s = self._faults.get("stalled_axis", {}).get("trip_s", 1.0)
        self._schedule(t_motion_end + trip_s, functools.partial(self._trip_following_error, axis))

    def _trip_following_error(self, axis: int, t: float) -> None:
        ax = self._axes[axis - 1]
        if not ax.stalled or ax.mode is AxisMode.OFF:
            return
        ax.following_error = True
        ax.brake(t)
        ax.mode = AxisMode.OFF
        self._push(QueuedError(AxisErrorCode.FOLLOWING_ERROR, "Following error", axis))

    def _trip_interlocks(self, t: float) -> None:
        for i, ax in enumerate(self._axes):
            ax.brake(t)
            ax.mode = AxisMode.OFF
            self._interlock[i] = Interlock.FAULT
            self._push(QueuedError(AxisErrorCode.INTERLOCK, "Interlock fault", i + 1))
        self._faults.pop("interlock_trip", None)
