"""Executes command lines of the table protocol on a :class:`TableController`.

One line in, one reply line out (``OK``, the query values joined by ``;``, or
``ERR <code>,"<text>"``). Wire axes (1 = inner) are mapped to the controller's
(1 = outermost) here and back in axis error codes.
"""

from __future__ import annotations

import functools
import logging
import re
from collections.abc import Callable
from typing import TypeVar

from drivers.base import AxisMode
from drivers.sim.table_controller import QueuedError, Rejected, TableController
from drivers.sim.table_grammar import (
    Command,
    CommandSyntaxError,
    format_error,
    format_error_entry,
    format_status,
    join_replies,
    parse_command_line,
)
from drivers.table_protocol import (
    MODE_KEYWORD,
    MODE_REPLY,
    OK,
    ScpiError,
    base_axis,
    device_error_code,
    format_number,
    wire_axis,
)

Args = tuple[str, ...]
T = TypeVar("T")
log = logging.getLogger(__name__)
DEVICE_SPECIFIC_ERROR = -300
_MODE_OF_KEYWORD = {kw: m for m, kw in MODE_KEYWORD.items()}
_INT = re.compile(r"^[+-]?\d+$")
_FLOAT = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")


class CommandSet:
    """The controller's command interpreter (stateless apart from the controller)."""

    def __init__(self, controller: TableController) -> None:
        self.ctl = controller
        self.n = controller.n_axes
        c = controller
        all_axes = self._axis_or_all
        self._commands: dict[tuple[str, ...], Callable[[Args], None]] = {
            ("*RST",): lambda a: self._no_args(a, c.reset),
            ("INTERLOCK", "CLOSE"): lambda a: c.interlock_close(all_axes(a)),
            ("INTERLOCK", "OPEN"): lambda a: c.interlock_open(all_axes(a)),
            ("INTERLOCK", "RESET"): lambda a: c.interlock_reset(all_axes(a)),
            ("DEMAND", "POSITION"): lambda a: c.demand_position(*self._axis_number(a)),
            ("DEMAND", "DELTA"): lambda a: c.demand_delta(*self._axis_number(a)),
            ("DEMAND", "RATE"): lambda a: c.demand_rate(*self._axis_number(a)),
            ("DEMAND", "OSCILLATION"): self._demand_osc,
            ("LIMIT", "RATE"): lambda a: self._set_limit("rate", a),
            ("LIMIT", "ACCELERATION"): lambda a: self._set_limit("acc", a),
            ("STOP",): lambda a: c.stop(all_axes(a)),
            ("ESTOP",): lambda a: self._no_args(a, c.estop),
            ("ESTOP", "RESET"): lambda a: self._no_args(a, c.estop_reset),
        }
        for kw, m in _MODE_OF_KEYWORD.items():
            self._commands[("MODE", kw)] = functools.partial(self._set_mode, mode=m)
        one = self._one_axis
        self._queries: dict[tuple[str, ...], Callable[[Args], str]] = {
            ("*IDN",): lambda a: self._no_args(a, c.identity),
            ("INTERLOCK",): lambda a: c.interlock_state(one(a)).value,
            ("MODE",): lambda a: MODE_REPLY[c.mode(one(a))],
            ("READ", "POSITION"): lambda a: format_number(c.read(one(a))[0]),
            ("READ", "RATE"): lambda a: format_number(c.read(one(a))[1]),
            ("READ", "ACCELERATION"): lambda a: format_number(c.read(one(a))[2]),
            ("STATUS",): lambda a: format_status(c.status(one(a))),
            ("LIMIT", "ABSOLUTE"): self._limits,
            ("SYSTEM", "ERROR"): self._error_query,
        }

    # ---- entry point -------------------------------------------------------------------
    def execute(self, line: str) -> str:
        """The reply line to ``line`` (never raises for bad input; errors are queued)."""
        try:
            commands = parse_command_line(line)
            replies = [self._run(cmd) for cmd in commands]
        except CommandSyntaxError as exc:
            self.ctl.push_error(exc.code, exc.text)
            return format_error(exc.code, exc.text)
        except Rejected as exc:
            return format_error(self._wire_code(exc.code, exc.axis), exc.text)
        except Exception as exc:  # a controller bug must not kill the connection
            log.exception("table controller failed on %r", line)
            self.ctl.push_error(DEVICE_SPECIFIC_ERROR, f"Device-specific error: {type(exc).__name__}")
            return format_error(DEVICE_SPECIFIC_ERROR, f"Device-specific error: {type(exc).__name__}")
        values = [r for r, cmd in zip(replies, commands, strict=True) if cmd.query]
        return join_replies(values) if values else OK

    def _run(self, cmd: Command) -> str:
        if cmd.query:
            query = self._queries.get(cmd.header)
            if query is None:
                raise CommandSyntaxError(ScpiError.UNDEFINED_HEADER, "Undefined header")
            return query(cmd.args)
        command = self._commands.get(cmd.header)
        if command is None:
            raise CommandSyntaxError(ScpiError.UNDEFINED_HEADER, "Undefined header")
        command(cmd.args)
        return OK

    def _wire_code(self, code: int, axis: int | None) -> int:
        return device_error_code(code, wire_axis(axis, self.n)) if axis is not None else code

    # ---- argument helpers --------------------------------------------------------------
    def _no_args(self, args: Args, action: Callable[[], T]) -> T:
        self._nargs(args, 0)
        return action()

    def _axis_or_all(self, args: Args) -> int | None:
        return self._axis(args, 1, True)[0]

    @staticmethod
    def _nargs(args: Args, count: int) -> None:
        if len(args) < count:
            raise CommandSyntaxError(ScpiError.MISSING_PARAMETER, "Missing parameter")
        if len(args) > count:
            raise CommandSyntaxError(ScpiError.PARAMETER_NOT_ALLOWED, "Parameter not allowed")

    def _axis(self, args: Args, count: int, allow_all: bool = False) -> tuple[int | None, ...]:
        """Parse ``args[0]`` as a wire axis (-> base number, ``None`` = ALL) after checking the count."""
        self._nargs(args, count)
        token = args[0].upper()
        if allow_all and token == "ALL":
            return (None,)
        if not _INT.match(token):
            raise CommandSyntaxError(ScpiError.DATA_TYPE, "Data type error: axis")
        wire = int(token)
        if not 1 <= wire <= self.n:
            raise CommandSyntaxError(ScpiError.DATA_OUT_OF_RANGE, f"Data out of range: axis {wire}")
        return (base_axis(wire, self.n),)

    def _one_axis(self, args: Args) -> int:
        axis = self._axis(args, 1)[0]
        assert axis is not None
        return axis

    @staticmethod
    def _number(token: str) -> float:
        if not _FLOAT.match(token):
            raise CommandSyntaxError(ScpiError.DATA_TYPE, f"Data type error: {token[:20]}")
        return float(token)

    def _axis_number(self, args: Args) -> tuple[int, float]:
        self._nargs(args, 2)
        axis = self._axis(args[:1], 1)[0]
        assert axis is not None
        return axis, self._number(args[1])

    # ---- composite handlers ------------------------------------------------------------
    def _demand_osc(self, args: Args) -> None:
        if len(args) == 3:
            args = (*args, "0")
        self._nargs(args, 4)
        axis = self._one_axis(args[:1])
        amp, freq, phase = (self._number(t) for t in args[1:])
        self.ctl.demand_oscillation(axis, amp, freq, phase)

    def _set_mode(self, args: Args, mode: AxisMode) -> None:
        self.ctl.set_mode(self._axis_or_all(args), mode)

    def _set_limit(self, kind: str, args: Args) -> None:
        self._nargs(args, 3)
        keyword = args[0].upper()
        mode = next((m for kw, m in _MODE_OF_KEYWORD.items() if keyword in (kw, kw[:3], kw[:4])), None)
        if mode is None or mode is AxisMode.OFF:
            raise CommandSyntaxError(ScpiError.DATA_TYPE, "Data type error: mode")
        axis = self._one_axis(args[1:2])
        self.ctl.set_limit(kind, mode, axis, self._number(args[2]))

    def _limits(self, args: Args) -> str:
        lim = self.ctl.absolute_limits(self._one_axis(args))
        values = (lim.rate_deg_s, lim.acc_deg_s2, 0.0, lim.pos_lo_deg, lim.pos_hi_deg, lim.vtrip_deg_s)
        return ",".join(format_number(v) for v in values)

    def _error_query(self, args: Args) -> str:
        self._nargs(args, 0)
        entry: QueuedError | None = self.ctl.pop_error()
        if entry is None:
            return format_error_entry(0, "No error")
        return format_error_entry(self._wire_code(entry.code, entry.axis), entry.text)
