"""The three-axis table's text protocol: encode commands, parse replies. No I/O.

An ACUTROL/SCPI-style line protocol (documented in ``docs/table-protocol.md``): ASCII
lines ending in ``\\r\\n`` (the transport adds and strips the terminator), exactly one
reply line per command line: ``OK``, a value, or ``ERR <code>,"<text>"``. Keywords have
a long and a SCPI short form (``:DEMAND:POSITION`` = ``:DEM:POS``), case-insensitive.
Commands chain with ``;``; a chained part without a leading ``:`` keeps the previous
part's path (``:READ:POSITION? 1;POSITION? 2``) and the reply parts are joined by ``;``.

Axis numbering on the wire: **1 = inner, 2 = middle, 3 = outer** (the controller's own
convention). ``drivers.base`` and the recording format number axes **1 = outermost**.
:func:`wire_axis` and :func:`base_axis` map between the two: wire = n_axes + 1 − base.

Error codes: SCPI negative codes, plus device codes ``100·axis + n`` (ESP300 style: the
wire axis digit then a two-digit code, see :class:`AxisErrorCode`).
"""

from __future__ import annotations

import enum
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

from drivers.base import AxisMode
from drivers.errors import ProtocolError

IDN_QUERY = "*IDN?"
RESET = "*RST"
ERROR_QUERY = ":SYSTEM:ERROR?"
ESTOP = ":ESTOP"
ESTOP_RESET = ":ESTOP:RESET"
OK = "OK"
NO_ERROR_CODE = 0
MAX_LINE_CHARS = 256
"""Longest line either side accepts; longer input is an error, never buffered forever."""


class Status(enum.IntFlag):
    """Per-axis status word, the reply to ``:STATUS? <ax>`` (four hex digits)."""

    IN_POSITION = 1 << 0
    """|position − demand| < window, held for the settle time (position mode)."""
    MOVING = 1 << 1
    AT_RATE = 1 << 2
    """|rate − demand| < tolerance (rate mode, after the ramp)."""
    INTERLOCK_CLOSED = 1 << 3
    ESTOP = 1 << 4
    PLUS_LIMIT = 1 << 5
    MINUS_LIMIT = 1 << 6
    FOLLOWING_ERROR = 1 << 7
    AMPLIFIER_FAULT = 1 << 8
    OVER_TEMPERATURE = 1 << 9
    NOT_REFERENCED = 1 << 10
    LIMIT_CLAMP = 1 << 11


FAULT_BITS = {
    Status.FOLLOWING_ERROR: "following error",
    Status.AMPLIFIER_FAULT: "amplifier fault",
    Status.OVER_TEMPERATURE: "over-temperature",
    Status.PLUS_LIMIT: "+limit",
    Status.MINUS_LIMIT: "-limit",
    Status.NOT_REFERENCED: "not referenced",
}
"""Status bits that mean an axis fault, with the text a driver reports."""


class ScpiError(enum.IntEnum):
    """SCPI error codes the controller uses."""

    SYNTAX = -102
    DATA_TYPE = -104
    PARAMETER_NOT_ALLOWED = -108
    MISSING_PARAMETER = -109
    UNDEFINED_HEADER = -113
    SETTINGS_CONFLICT = -221
    DATA_OUT_OF_RANGE = -222
    QUEUE_OVERFLOW = -350


class AxisErrorCode(enum.IntEnum):
    """Two-digit device codes n in ``100·wire_axis + n`` (ESP300 numbering)."""

    AMPLIFIER_FAULT = 2
    FOLLOWING_ERROR = 3
    HARDWARE_LIMIT_PLUS = 4
    HARDWARE_LIMIT_MINUS = 5
    SOFTWARE_LIMIT_PLUS = 6
    SOFTWARE_LIMIT_MINUS = 7
    INTERLOCK = 9
    ESTOP = 12


class Interlock(enum.Enum):
    """Reply to ``:INTERLOCK? <ax>``."""

    CLOSED = "Closed"
    OPEN = "Open"
    FAULT = "Fault"


MODE_KEYWORD = {
    AxisMode.OFF: "OFF",
    AxisMode.POSITION: "POSITION",
    AxisMode.RATE: "RATE",
    AxisMode.OSCILLATION: "SYNTHESIS",
}
"""Keyword of each mode in ``:MODE:<kw>`` and ``:LIMIT:RATE <kw>,...``."""
MODE_REPLY = {
    AxisMode.OFF: "Off",
    AxisMode.POSITION: "Position",
    AxisMode.RATE: "Rate",
    AxisMode.OSCILLATION: "Synthesis",
}
"""Reply of ``:MODE? <ax>`` for each mode."""


def wire_axis(axis: int, n_axes: int) -> int:
    """Wire axis number (1 = inner) of base axis ``axis`` (1 = outermost)."""
    if not 1 <= axis <= n_axes:
        raise ValueError(f"axis must be in 1..{n_axes} (1 = outermost), got {axis!r}")
    return n_axes + 1 - axis


def base_axis(wire: int, n_axes: int) -> int:
    """Base axis number (1 = outermost) of wire axis ``wire`` (1 = inner)."""
    if not 1 <= wire <= n_axes:
        raise ValueError(f"wire axis must be in 1..{n_axes} (1 = inner), got {wire!r}")
    return n_axes + 1 - wire


def device_error_code(n: int, wire: int) -> int:
    """Device error code ``100·wire + n`` for axis fault ``n`` on wire axis ``wire``."""
    return 100 * wire + n


def split_device_error_code(code: int) -> tuple[int, int] | None:
    """(wire axis, n) of a device error code, ``None`` for SCPI and general codes."""
    if code < 100:
        return None
    return code // 100, code % 100


# ---- numbers -----------------------------------------------------------------------

_NUMBER = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")


def format_number(value: float) -> str:
    """Reply/argument form of a number: sign, ≥ 3 integer digits, 5 decimals (``+090.00012``)."""
    if not math.isfinite(value):
        raise ValueError(f"cannot send a non-finite number: {value!r}")
    return f"{value:+010.5f}"


def parse_number(text: str, line: str | None = None) -> float:
    """A finite decimal number; ``nan``/``inf`` and anything else raise :class:`ProtocolError`."""
    token = text.strip()
    if not _NUMBER.match(token):
        raise ProtocolError("expected a number", line if line is not None else text)
    return float(token)


# ---- host side: commands -----------------------------------------------------------


def _axis_arg(axis: int | None) -> str:
    return "ALL" if axis is None else str(int(axis))


def interlock(action: str, wire: int | None) -> str:
    """``:INTERLOCK:CLOSE|OPEN|RESET <ax>|ALL``."""
    if action not in ("CLOSE", "OPEN", "RESET"):
        raise ValueError(f"interlock action must be CLOSE, OPEN or RESET, got {action!r}")
    return f":INTERLOCK:{action} {_axis_arg(wire)}"


def interlock_query(wire: int) -> str:
    return f":INTERLOCK? {wire}"


def mode(mode_: AxisMode, wire: int | None) -> str:
    """``:MODE:<OFF|POSITION|RATE|SYNTHESIS> <ax>|ALL``."""
    return f":MODE:{MODE_KEYWORD[mode_]} {_axis_arg(wire)}"


def mode_query(wire: int) -> str:
    return f":MODE? {wire}"


def demand_position(wire: int, angle_deg: float) -> str:
    """Absolute position demand (deg, −180…+180)."""
    return f":DEMAND:POSITION {wire},{format_number(angle_deg)}"


def demand_delta(wire: int, delta_deg: float) -> str:
    """Relative position demand (deg, |Δ| ≤ 180)."""
    return f":DEMAND:DELTA {wire},{format_number(delta_deg)}"


def demand_rate(wire: int, rate_deg_s: float) -> str:
    return f":DEMAND:RATE {wire},{format_number(rate_deg_s)}"


def demand_oscillation(wire: int, amplitude_deg: float, frequency_hz: float, phase_deg: float = 0.0) -> str:
    """Sinusoidal demand A·sin(2πft + φ) about the current position (synthesis mode)."""
    return (
        f":DEMAND:OSC {wire},{format_number(amplitude_deg)},{format_number(frequency_hz)},"
        f"{format_number(phase_deg)}"
    )


READ_KEYWORDS = {"position": "POSITION", "rate": "RATE", "acc": "ACC"}


def read_query(quantity: str, wires: Sequence[int]) -> str:
    """``:READ:POSITION? a;POSITION? b`` — one chained query over several axes."""
    kw = READ_KEYWORDS[quantity]
    return ";".join(f"{':READ:' if i == 0 else ''}{kw}? {w}" for i, w in enumerate(wires))


def status_query(wire: int) -> str:
    return f":STATUS? {wire}"


def axis_state_query(wire: int) -> str:
    """One chained query for an axis: status word, mode, interlock, position, rate."""
    return f":STATUS? {wire};:MODE? {wire};:INTERLOCK? {wire};:READ:POSITION? {wire};RATE? {wire}"


def limit_rate(mode_: AxisMode, wire: int, rate_deg_s: float) -> str:
    return f":LIMIT:RATE {MODE_KEYWORD[mode_]},{wire},{format_number(rate_deg_s)}"


def limit_acc(mode_: AxisMode, wire: int, acc_deg_s2: float) -> str:
    return f":LIMIT:ACC {MODE_KEYWORD[mode_]},{wire},{format_number(acc_deg_s2)}"


def limit_absolute_query(wire: int) -> str:
    return f":LIMIT:ABSOLUTE? {wire}"


def stop(wire: int | None) -> str:
    """``:STOP <ax>|ALL``: decelerate to rest, stay in mode."""
    return f":STOP {_axis_arg(wire)}"


# ---- host side: replies ------------------------------------------------------------

_PRINTABLE = re.compile(r"^[\x20-\x7e]*$")
_ERR = re.compile(r'^ERR (-?\d+),"([^"]*)"$')
_ERROR_ENTRY = re.compile(r'^(-?\d+),"([^"]*)"$')
_HEX4 = re.compile(r"^[0-9A-Fa-f]{4}$")


def check_line(line: str) -> str:
    """``line`` if it is printable ASCII and not overlong, else :class:`ProtocolError`."""
    if len(line) > MAX_LINE_CHARS:
        raise ProtocolError(f"reply longer than {MAX_LINE_CHARS} characters", line)
    if not _PRINTABLE.match(line):
        raise ProtocolError("reply holds characters outside printable ASCII", line)
    return line


def is_error(line: str) -> bool:
    """The reply is an ``ERR`` line."""
    return line.startswith("ERR ")


def parse_error(line: str) -> tuple[int, str]:
    """(code, text) of an ``ERR <code>,"<text>"`` reply."""
    m = _ERR.match(line)
    if not m:
        raise ProtocolError('expected ERR <code>,"<text>"', line)
    return int(m.group(1)), m.group(2)


def parse_error_entry(line: str) -> tuple[int, str]:
    """(code, text) of a ``:SYSTEM:ERROR?`` reply; code 0 means the queue is empty."""
    m = _ERROR_ENTRY.match(line)
    if not m:
        raise ProtocolError('expected <code>,"<text>" from :SYSTEM:ERROR?', line)
    return int(m.group(1)), m.group(2)


def parse_ok(line: str) -> None:
    if line != OK:
        raise ProtocolError("expected OK", line)


def parse_numbers(line: str, count: int) -> tuple[float, ...]:
    """``count`` numbers separated by ``;`` (a chained read) or ``,`` (a limit list)."""
    parts = re.split(r"[;,]", line)
    if len(parts) != count:
        raise ProtocolError(f"expected {count} number(s)", line)
    return tuple(parse_number(p, line) for p in parts)


def parse_status(text: str, line: str | None = None) -> Status:
    if not _HEX4.match(text):
        raise ProtocolError("expected a four-digit hex status word", line if line is not None else text)
    return Status(int(text, 16))


def parse_mode(text: str, line: str | None = None) -> AxisMode:
    for m, reply in MODE_REPLY.items():
        if text == reply:
            return m
    raise ProtocolError(f"expected one of {sorted(MODE_REPLY.values())}", line if line is not None else text)


def parse_interlock(text: str, line: str | None = None) -> Interlock:
    try:
        return Interlock(text)
    except ValueError:
        raise ProtocolError("expected Closed, Open or Fault", line if line is not None else text) from None


@dataclass(frozen=True)
class AxisState:
    """Decoded reply to :func:`axis_state_query`."""

    status: Status
    mode: AxisMode
    interlock: Interlock
    position_deg: float
    rate_deg_s: float


def parse_axis_state(line: str) -> AxisState:
    parts = line.split(";")
    if len(parts) != 5:
        raise ProtocolError("expected status;mode;interlock;position;rate", line)
    return AxisState(
        parse_status(parts[0], line),
        parse_mode(parts[1], line),
        parse_interlock(parts[2], line),
        parse_number(parts[3], line),
        parse_number(parts[4], line),
    )


@dataclass(frozen=True)
class AbsoluteLimits:
    """Reply to ``:LIMIT:ABSOLUTE? <ax>`` (deg, deg/s, deg/s², deg/s³; jerk 0 = not limited)."""

    rate_deg_s: float
    acc_deg_s2: float
    jerk_deg_s3: float
    pos_lo_deg: float
    pos_hi_deg: float
    vtrip_deg_s: float


def parse_limits(line: str) -> AbsoluteLimits:
    return AbsoluteLimits(*parse_numbers(line, 6))


def parse_idn(line: str) -> tuple[str, str, str, str]:
    """(maker, model, serial, firmware) of an ``*IDN?`` reply."""
    parts = line.split(",")
    if len(parts) != 4 or not all(p.strip() for p in parts):
        raise ProtocolError("expected maker,model,serial,firmware", line)
    return parts[0], parts[1], parts[2], parts[3]
