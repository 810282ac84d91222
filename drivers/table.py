"""SerialRotaryTable: the three-axis table driver (``drivers.base.RotaryTable``).

:mod:`drivers.table_protocol` (what the lines say) over :mod:`drivers.transport` (how
they travel). Rules it keeps:

* one command in flight (a lock around every command/reply pair);
* a deadline per call, not per byte; a move's polling never outlives ``move_to``'s timeout;
* after every ``ERR`` reply it drains ``:SYSTEM:ERROR?`` until ``0`` and puts the entries
  in the raised error: ``LimitError`` (−222, software/hardware limit codes),
  ``InterlockOpen`` (interlock and E-stop codes), ``DeviceError`` (anything else);
* replies it cannot parse raise ``ProtocolError`` carrying the line, a silent device
  ``DeviceTimeout``, a dropped port ``LinkLost``.

Axis numbers in this API are ``drivers.base``'s (1 = outermost); the wire's (1 = inner)
are only used inside. Stop semantics: :meth:`stop` (the ``RotaryTable.stop``) is
``:STOP ALL`` — decelerate and hold, servo on, mode kept. :meth:`make_safe` is the abort
path: ``:STOP ALL``, wait for rest, ``:MODE:OFF ALL``, ``:INTERLOCK:OPEN ALL``.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from typing import Protocol

from drivers import table_protocol as tp
from drivers.base import AxisMode, AxisStatus, TableStatus
from drivers.errors import DeviceError, DeviceTimeout, DriverError, InterlockOpen, LimitError, ProtocolError
from drivers.transport import LineTransport

MAX_ERROR_DRAIN = 20
"""Most ``:SYSTEM:ERROR?`` reads after one error (the queue holds 10)."""


class QueryTransport(Protocol):
    """What the driver needs from a transport (a :class:`LineTransport` or a test fake)."""

    def query(self, line: str, timeout_s: float) -> str: ...

    def close(self) -> None: ...


class SerialRotaryTable:
    """A rotary table on a serial line or TCP socket speaking ``docs/table-protocol.md``.

    :param url: pyserial port or URL (``/dev/ttyUSB0``, ``serial:///dev/ttyS0?baud=115200``,
        ``socket://host:port``). Opening sends nothing; :meth:`identify` checks the link.
    :param timeout_s: deadline of one command/reply pair (wall s).
    :param n_axes: number of axes.
    :param poll_interval_s: pause between status polls while waiting for motion (wall s).
    :param position_tol_deg: largest |readback − demand| accepted as "arrived" (deg), on
        top of the controller's own in-position flag.
    :param transport: use this instead of opening ``url`` (tests).
    """

    def __init__(
        self,
        url: str,
        *,
        timeout_s: float = 1.0,
        n_axes: int = 3,
        poll_interval_s: float = 0.05,
        position_tol_deg: float = 0.01,
        transport: QueryTransport | None = None,
    ) -> None:
        if not (math.isfinite(timeout_s) and timeout_s > 0):
            raise ValueError(f"timeout_s must be finite and > 0, got {timeout_s!r}")
        if not 1 <= n_axes <= 9:
            raise ValueError(f"n_axes must be 1..9, got {n_axes!r}")
        self.url = url
        self.timeout_s = timeout_s
        self.poll_interval_s = poll_interval_s
        self.position_tol_deg = position_tol_deg
        self._n_axes = n_axes
        self._lock = threading.RLock()
        self._limits: dict[int, tp.AbsoluteLimits] = {}
        self._transport: QueryTransport = transport if transport is not None else LineTransport(url)

    @property
    def n_axes(self) -> int:
        return self._n_axes

    # ---- one command -------------------------------------------------------------------
    def _wire(self, axis: int) -> int:
        return tp.wire_axis(axis, self._n_axes)

    def query(self, line: str, deadline: float | None = None) -> str:
        """Send one line, return its reply; raise the typed error for ``ERR`` replies.

        :param deadline: ``time.monotonic()`` value the reply must arrive by (the command
            timeout applies as well).
        """
        with self._lock:
            timeout = self.timeout_s
            if deadline is not None:
                timeout = min(timeout, deadline - time.monotonic())
                if timeout <= 0:
                    raise DeviceTimeout(f"{self.url}: no time left to send {line!r}")
            try:
                reply = self._transport.query(line, timeout)
            except DeviceTimeout as exc:
                raise DeviceTimeout(
                    f"{self.url}: no reply to {line!r} within {timeout:.3g} s ({exc})"
                ) from exc
            except ProtocolError as exc:
                raise ProtocolError(f"{self.url}: unreadable reply to {line!r}", exc.line) from exc
            try:
                tp.check_line(reply)
            except ProtocolError as exc:
                raise ProtocolError(f"{self.url}: garbled reply to {line!r}", reply) from exc
            if tp.is_error(reply):
                code, text = tp.parse_error(reply)
                raise self._typed_error(line, code, text, self._drain_errors())
            return reply

    def command(self, line: str, deadline: float | None = None) -> None:
        """Send a command that must answer ``OK``."""
        reply = self.query(line, deadline)
        if reply != tp.OK:
            raise ProtocolError(f"{self.url}: expected OK to {line!r}", reply)

    def _drain_errors(self) -> list[str]:
        entries: list[str] = []
        try:
            for _ in range(MAX_ERROR_DRAIN):
                line = self._transport.query(tp.ERROR_QUERY, self.timeout_s)
                code, text = tp.parse_error_entry(tp.check_line(line))
                if code == tp.NO_ERROR_CODE:
                    break
                entries.append(f"{code},{text}")
        except DriverError as exc:
            entries.append(f"(error queue unreadable: {exc})")
        return entries

    def _typed_error(self, line: str, code: int, text: str, queued: list[str]) -> DriverError:
        message = f"{self.url}: {line!r} refused: {code} {text}"
        if queued:
            message += f"; error queue: {'; '.join(queued)}"
        axis_code = tp.split_device_error_code(code)
        n = axis_code[1] if axis_code else None
        if code == tp.ScpiError.DATA_OUT_OF_RANGE or n in (4, 5, 6, 7):
            return LimitError(message)
        if n in (tp.AxisErrorCode.INTERLOCK, tp.AxisErrorCode.ESTOP):
            return InterlockOpen(message)
        return DeviceError(message, code)

    def errors(self) -> tuple[str, ...]:
        """Drain the controller's error queue (``code,text`` entries, oldest first)."""
        with self._lock:
            return tuple(self._drain_errors())

    # ---- reads -------------------------------------------------------------------------
    def identify(self) -> str:
        """``*IDN?`` reply, checked for its four fields (also proves the link works)."""
        reply = self.query(tp.IDN_QUERY)
        tp.parse_idn(reply)
        return reply

    def limits(self, axis: int) -> tp.AbsoluteLimits:
        """Absolute limits of ``axis`` (cached after the first read)."""
        if axis not in self._limits:
            self._limits[axis] = tp.parse_limits(self.query(tp.limit_absolute_query(self._wire(axis))))
        return self._limits[axis]

    def axis_state(self, axis: int, deadline: float | None = None) -> tp.AxisState:
        """Status word, mode, interlock, position and rate of one axis, in one exchange."""
        return tp.parse_axis_state(self.query(tp.axis_state_query(self._wire(axis)), deadline))

    def _read_all(self, quantity: str) -> tuple[float, ...]:
        wires = [self._wire(a) for a in range(1, self._n_axes + 1)]
        return tp.parse_numbers(self.query(tp.read_query(quantity, wires)), self._n_axes)

    def positions_deg(self) -> tuple[float, ...]:
        return self._read_all("position")

    def rates_deg_s(self) -> tuple[float, ...]:
        return self._read_all("rate")

    def status(self) -> TableStatus:
        with self._lock:
            states = [self.axis_state(a) for a in range(1, self._n_axes + 1)]
            errors = self._drain_errors()
        axes = tuple(
            AxisStatus(
                s.position_deg, s.rate_deg_s, s.mode, bool(s.status & tp.Status.IN_POSITION), _fault_text(s)
            )
            for s in states
        )
        return TableStatus(
            axes=axes,
            interlock_ok=all(s.status & tp.Status.INTERLOCK_CLOSED for s in states),
            estop=any(s.status & tp.Status.ESTOP for s in states),
            errors=tuple(errors),
        )

    # ---- motion ------------------------------------------------------------------------
    def _check_ready(self, axis: int, state: tp.AxisState) -> None:
        if state.status & tp.Status.ESTOP:
            raise InterlockOpen(f"{self.url}: E-stop latched (axis {axis}); {self._drain_errors()}")
        if state.interlock is not tp.Interlock.CLOSED:
            raise InterlockOpen(
                f"{self.url}: interlock {state.interlock.value} on axis {axis}; "
                f"errors: {self._drain_errors()}"
            )
        fault = _fault_text(state)
        if fault:
            raise DeviceError(f"{self.url}: axis {axis} fault: {fault}; errors: {self._drain_errors()}")

    def _ensure_mode(self, axis: int, mode: AxisMode, deadline: float) -> None:
        state = self.axis_state(axis, deadline)
        self._check_ready(axis, state)
        if state.mode is mode:
            return
        if state.status & tp.Status.MOVING:
            self.command(tp.stop(self._wire(axis)), deadline)
            self._wait(deadline, lambda: not self._moving(axis, deadline), f"axis {axis} to stop")
        self.command(tp.mode(mode, self._wire(axis)), deadline)

    def _moving(self, axis: int, deadline: float) -> bool:
        return bool(self.axis_state(axis, deadline).status & tp.Status.MOVING)

    def _wait(self, deadline: float, done: _Predicate, what: str) -> None:
        while not done():
            if time.monotonic() + self.poll_interval_s > deadline:
                raise DeviceTimeout(f"{self.url}: timed out waiting for {what}")
            time.sleep(self.poll_interval_s)

    def move_to(self, angles_deg: tuple[float, ...], timeout_s: float) -> None:
        """Demand every axis's angle (deg, wrapped to −180…180) and wait for in-position on all.

        Limits are checked against ``:LIMIT:ABSOLUTE?`` before anything moves. On timeout the
        axes are left as they are (call :meth:`stop` or :meth:`make_safe`).
        """
        targets = self._targets(angles_deg)
        deadline = time.monotonic() + timeout_s
        with self._lock:
            for axis in range(1, self._n_axes + 1):
                self._ensure_mode(axis, AxisMode.POSITION, deadline)
            for axis, target in enumerate(targets, start=1):
                self.command(tp.demand_position(self._wire(axis), target), deadline)
            last: list[tp.AxisState] = []

            def arrived() -> bool:
                last[:] = [self.axis_state(a, deadline) for a in range(1, self._n_axes + 1)]
                for a, state in enumerate(last, start=1):
                    self._check_ready(a, state)
                    if state.mode is not AxisMode.POSITION:
                        raise DeviceError(
                            f"{self.url}: axis {a} left position mode ({state.mode.name}) "
                            f"during the move; errors: {self._drain_errors()}"
                        )
                return all(
                    bool(s.status & tp.Status.IN_POSITION)
                    and abs(_wrap(s.position_deg - t)) <= self.position_tol_deg
                    for s, t in zip(last, targets, strict=True)
                )

            try:
                self._wait(deadline, arrived, f"in-position at {targets}")
            except DeviceTimeout as exc:
                where = [s.position_deg for s in last]
                raise DeviceTimeout(f"{exc} (last positions {where} deg)") from exc

    def _targets(self, angles_deg: Sequence[float]) -> tuple[float, ...]:
        if len(angles_deg) != self._n_axes:
            raise ValueError(
                f"move_to: expected {self._n_axes} angles (outermost first), got {len(angles_deg)}"
            )
        targets = []
        for axis, angle in enumerate(angles_deg, start=1):
            if not math.isfinite(angle):
                raise ValueError(f"move_to: angle of axis {axis} is not finite: {angle!r}")
            wrapped = _wrap(float(angle))
            lim = self.limits(axis)
            if not lim.pos_lo_deg <= wrapped <= lim.pos_hi_deg:
                raise LimitError(
                    f"{self.url}: axis {axis} angle {angle} deg outside its limits "
                    f"[{lim.pos_lo_deg}, {lim.pos_hi_deg}] deg"
                )
            targets.append(wrapped)
        return tuple(targets)

    def start_rate(self, axis: int, rate_deg_s: float, timeout_s: float = 60.0) -> None:
        """Rate mode at ``rate_deg_s``; returns once accepted (stops the axis first if it moves)."""
        if not math.isfinite(rate_deg_s):
            raise ValueError(f"start_rate: rate must be finite, got {rate_deg_s!r}")
        lim = self.limits(axis)
        if abs(rate_deg_s) > lim.rate_deg_s:
            raise LimitError(
                f"{self.url}: axis {axis} rate {rate_deg_s} deg/s above its limit {lim.rate_deg_s}"
            )
        deadline = time.monotonic() + timeout_s
        with self._lock:
            self._ensure_mode(axis, AxisMode.RATE, deadline)
            self.command(tp.demand_rate(self._wire(axis), rate_deg_s), deadline)

    def start_oscillation(
        self, axis: int, amplitude_deg: float, period_s: float, timeout_s: float = 60.0
    ) -> None:
        """Synthesis mode, A·sin(2πt/T) about where the axis stands (the controller ramps it in)."""
        if not (
            math.isfinite(amplitude_deg) and amplitude_deg >= 0 and math.isfinite(period_s) and period_s > 0
        ):
            raise ValueError(
                f"start_oscillation: need amplitude >= 0 and period > 0, got {amplitude_deg!r}, {period_s!r}"
            )
        deadline = time.monotonic() + timeout_s
        with self._lock:
            self._ensure_mode(axis, AxisMode.OSCILLATION, deadline)
            self.command(tp.demand_oscillation(self._wire(axis), amplitude_deg, 1.0 / period_s), deadline)

    def stop(self) -> None:
        """``:STOP ALL``: every axis decelerates to rest and holds, servo on. Returns once accepted."""
        self.command(tp.stop(None))

    def wait_until_stopped(self, timeout_s: float) -> None:
        """Block until no axis reports MOVING."""
        deadline = time.monotonic() + timeout_s
        self._wait(
            deadline,
            lambda: not any(self._moving(a, deadline) for a in range(1, self._n_axes + 1)),
            "all axes to stop",
        )

    def make_safe(self, timeout_s: float = 30.0) -> None:
        """Abort path: ``:STOP ALL``, wait for rest, ``:MODE:OFF ALL``, ``:INTERLOCK:OPEN ALL``.

        Every step is attempted even if an earlier one failed; the first failure is raised
        at the end.
        """
        first: DriverError | None = None
        steps = (
            self.stop,
            lambda: self.wait_until_stopped(timeout_s),
            lambda: self.command(tp.mode(AxisMode.OFF, None)),
            lambda: self.command(tp.interlock("OPEN", None)),
        )
        for step in steps:
            try:
                step()
            except DriverError as exc:
                first = first or exc
        if first is not None:
            raise first

    def prepare(self, timeout_s: float = 60.0) -> None:
        """Ready for a run: clear the error queue, reset faults, close interlocks, position mode."""
        deadline = time.monotonic() + timeout_s
        with self._lock:
            self._drain_errors()
            for axis in range(1, self._n_axes + 1):
                wire = self._wire(axis)
                state = self.axis_state(axis, deadline)
                if state.interlock is tp.Interlock.FAULT or _fault_text(state):
                    self.command(tp.interlock("RESET", wire), deadline)
                if state.interlock is not tp.Interlock.CLOSED:
                    self.command(tp.interlock("CLOSE", wire), deadline)
                self._ensure_mode(axis, AxisMode.POSITION, deadline)

    def close(self) -> None:
        self._transport.close()

    def __enter__(self) -> SerialRotaryTable:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _Predicate(Protocol):
    def __call__(self) -> bool: ...


def _wrap(angle_deg: float) -> float:
    return (angle_deg + 180.0) % 360.0 - 180.0


def _fault_text(state: tp.AxisState) -> str | None:
    faults = [text for bit, text in tp.FAULT_BITS.items() if state.status & bit]
    if state.interlock is tp.Interlock.FAULT:
        faults.append("interlock fault")
    return ", ".join(faults) or None
