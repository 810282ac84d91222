"""Table protocol: pure encode/parse, and the driver's exchanges as message pairs.

Every exchange is written out as the (command, reply) lines on the wire; the scripted
transport fails on any other line and on anything left unsent.
"""

from __future__ import annotations

import math

import pytest

from drivers import table_protocol as tp
from drivers.base import AxisMode
from drivers.errors import DeviceError, DeviceTimeout, InterlockOpen, LimitError, ProtocolError

from .table_fakes import expected_protocol

IDN = "SIMTABLE,3AX-100,SN0001,FW2.3"
NO_ERR = (":SYSTEM:ERROR?", '0,"No error"')
LIMITS = "+200.00000,+200.00000,+000.00000,-180.00000,+180.00000,+220.00000"
LIMIT_PAIRS = [(f":LIMIT:ABSOLUTE? {w}", LIMITS) for w in (3, 2, 1)]


def state_q(wire: int) -> str:
    return f":STATUS? {wire};:MODE? {wire};:INTERLOCK? {wire};:READ:POSITION? {wire};RATE? {wire}"


def state_r(
    status: int, mode: str = "Position", interlock: str = "Closed", pos: float = 0.0, rate: float = 0.0
) -> str:
    return f"{status:04X};{mode};{interlock};{tp.format_number(pos)};{tp.format_number(rate)}"


READY = 0x0009  # in position + interlock closed
MOVING = 0x000A  # moving + interlock closed


# ---- pure protocol ---------------------------------------------------------------------


@pytest.mark.parametrize(("base", "wire"), [(1, 3), (2, 2), (3, 1)])
def test_axis_numbering_outermost_first_maps_to_inner_first(base: int, wire: int) -> None:
    assert tp.wire_axis(base, 3) == wire
    assert tp.base_axis(wire, 3) == base


def test_axis_numbering_two_axes_and_bad_axis() -> None:
    assert tp.wire_axis(1, 2) == 2
    with pytest.raises(ValueError, match=r"1\.\.3"):
        tp.wire_axis(0, 3)
    with pytest.raises(ValueError, match=r"1\.\.3"):
        tp.base_axis(4, 3)


@pytest.mark.parametrize(
    ("value", "text"),
    [(90.00012, "+090.00012"), (-0.5, "-000.50000"), (1234.5, "+1234.50000"), (0.0, "+000.00000")],
)
def test_number_format(value: float, text: str) -> None:
    assert tp.format_number(value) == text
    assert tp.parse_number(text) == pytest.approx(value, abs=5e-6)


@pytest.mark.parametrize("bad", ["nan", "inf", "+09#.00", "", "1,2", "0x10"])
def test_parse_number_rejects_with_the_line(bad: str) -> None:
    with pytest.raises(ProtocolError) as info:
        tp.parse_number(bad)
    assert info.value.line == bad


def test_format_number_refuses_non_finite() -> None:
    with pytest.raises(ValueError):
        tp.format_number(math.nan)


def test_status_word_bits() -> None:
    # 0x0A19 = bits 0, 3, 4, 9, 11
    s = tp.parse_status("0A19")
    assert s == (
        tp.Status.IN_POSITION
        | tp.Status.INTERLOCK_CLOSED
        | tp.Status.ESTOP
        | tp.Status.OVER_TEMPERATURE
        | tp.Status.LIMIT_CLAMP
    )
    assert tp.parse_status("0a19") == s


@pytest.mark.parametrize("bad", ["9", "00G1", "00011", ""])
def test_status_word_must_be_four_hex_digits(bad: str) -> None:
    with pytest.raises(ProtocolError):
        tp.parse_status(bad)


def test_error_replies_and_entries() -> None:
    assert tp.parse_error('ERR -222,"Data out of range"') == (-222, "Data out of range")
    assert tp.parse_error_entry('109,"Interlock open"') == (109, "Interlock open")
    assert tp.split_device_error_code(312) == (3, 12)
    assert tp.split_device_error_code(-221) is None
    with pytest.raises(ProtocolError):
        tp.parse_error("ERR nonsense")


def test_check_line_rejects_control_and_8bit_characters() -> None:
    for bad in ("+0\x0190.0", "O\x8bK", "x" * 300):
        with pytest.raises(ProtocolError) as info:
            tp.check_line(bad)
        assert info.value.line == bad


def test_encoders_spell_the_documented_commands() -> None:
    assert tp.interlock("CLOSE", None) == ":INTERLOCK:CLOSE ALL"
    assert tp.mode(AxisMode.OSCILLATION, 2) == ":MODE:SYNTHESIS 2"
    assert tp.demand_position(1, -90.0) == ":DEMAND:POSITION 1,-090.00000"
    assert tp.demand_delta(1, 5.0) == ":DEMAND:DELTA 1,+005.00000"
    assert tp.demand_rate(3, 10.0) == ":DEMAND:RATE 3,+010.00000"
    assert tp.demand_oscillation(2, 1.0, 0.5) == ":DEMAND:OSC 2,+001.00000,+000.50000,+000.00000"
    assert tp.read_query("rate", [3, 2, 1]) == ":READ:RATE? 3;RATE? 2;RATE? 1"
    assert tp.limit_rate(AxisMode.POSITION, 1, 50.0) == ":LIMIT:RATE POSITION,1,+050.00000"
    assert tp.limit_acc(AxisMode.RATE, 1, 50.0) == ":LIMIT:ACC RATE,1,+050.00000"
    assert tp.stop(None) == ":STOP ALL"
    with pytest.raises(ValueError):
        tp.interlock("SLAM", 1)


# ---- driver message pairs --------------------------------------------------------------


def test_identify() -> None:
    with expected_protocol([("*IDN?", IDN)]) as t:
        assert t.identify() == IDN


def test_identify_rejects_a_foreign_device() -> None:
    with expected_protocol([("*IDN?", "HELLO")]) as t, pytest.raises(ProtocolError) as info:
        t.identify()
    assert info.value.line == "HELLO"


def test_positions_and_rates_outermost_first() -> None:
    pairs = [
        (":READ:POSITION? 3;POSITION? 2;POSITION? 1", "+010.00000;-090.00000;+045.00000"),
        (":READ:RATE? 3;RATE? 2;RATE? 1", "+000.00000;+001.50000;-002.00000"),
    ]
    with expected_protocol(pairs) as t:
        assert t.positions_deg() == (10.0, -90.0, 45.0)
        assert t.rates_deg_s() == (0.0, 1.5, -2.0)


def test_status_decodes_every_axis_and_drains_errors() -> None:
    pairs = [
        (state_q(3), state_r(READY, pos=10.0)),
        (state_q(2), state_r(0x0080, mode="Off", interlock="Fault", pos=-5.0)),
        (state_q(1), state_r(0x001E, mode="Rate", interlock="Closed", rate=20.0)),
        (":SYSTEM:ERROR?", '203,"Following error"'),
        NO_ERR,
    ]
    with expected_protocol(pairs) as t:
        s = t.status()
    assert [a.position_deg for a in s.axes] == [10.0, -5.0, 0.0]
    assert [a.mode for a in s.axes] == [AxisMode.POSITION, AxisMode.OFF, AxisMode.RATE]
    assert [a.in_position for a in s.axes] == [True, False, False]
    assert s.axes[1].fault == "following error, interlock fault"
    assert s.axes[2].rate_deg_s == 20.0
    assert not s.interlock_ok  # axis 2 open
    assert s.estop  # axis 3 reports the E-stop bit
    assert s.errors == ("203,Following error",)


def test_move_to_demands_then_polls_until_in_position() -> None:
    pairs = [
        *LIMIT_PAIRS,
        (state_q(3), state_r(READY)),
        (state_q(2), state_r(READY)),
        (state_q(1), state_r(READY)),
        (":DEMAND:POSITION 3,+010.00000", "OK"),
        (":DEMAND:POSITION 2,-090.00000", "OK"),
        (":DEMAND:POSITION 1,+045.00000", "OK"),
        (state_q(3), state_r(MOVING, pos=5.0)),
        (state_q(2), state_r(MOVING, pos=-40.0)),
        (state_q(1), state_r(MOVING, pos=20.0)),
        (state_q(3), state_r(READY, pos=10.0)),
        (state_q(2), state_r(READY, pos=-90.0)),
        (state_q(1), state_r(READY, pos=45.0)),
    ]
    with expected_protocol(pairs) as t:
        t.move_to((10.0, 270.0, 45.0), timeout_s=30.0)  # 270 is sent wrapped as -90


def test_move_to_stops_a_rotating_axis_before_position_mode() -> None:
    pairs = [
        *LIMIT_PAIRS,
        (state_q(3), state_r(0x000E, mode="Rate", rate=20.0)),
        (":STOP 3", "OK"),
        (state_q(3), state_r(0x000A, mode="Rate", rate=3.0)),
        (state_q(3), state_r(0x000C, mode="Rate")),
        (":MODE:POSITION 3", "OK"),
        (state_q(2), state_r(READY)),
        (state_q(1), state_r(READY)),
        (":DEMAND:POSITION 3,+000.00000", "OK"),
        (":DEMAND:POSITION 2,+000.00000", "OK"),
        (":DEMAND:POSITION 1,+000.00000", "OK"),
        (state_q(3), state_r(READY)),
        (state_q(2), state_r(READY)),
        (state_q(1), state_r(READY)),
    ]
    with expected_protocol(pairs) as t:
        t.move_to((0.0, 0.0, 0.0), timeout_s=30.0)


def test_move_to_checks_limits_before_anything_moves() -> None:
    limited = "+200.00000,+200.00000,+000.00000,-120.00000,+120.00000,+220.00000"
    pairs = [(":LIMIT:ABSOLUTE? 3", LIMITS), (":LIMIT:ABSOLUTE? 2", limited)]
    with expected_protocol(pairs) as t, pytest.raises(LimitError, match="axis 2"):
        t.move_to((0.0, 150.0, 0.0), timeout_s=5.0)


@pytest.mark.parametrize("angles", [(0.0, math.nan, 0.0), (0.0, 0.0)])
def test_move_to_refuses_bad_angles_without_a_word_on_the_wire(angles: tuple[float, ...]) -> None:
    with (
        expected_protocol([(":LIMIT:ABSOLUTE? 3", LIMITS)] if len(angles) == 3 else []) as t,
        pytest.raises(ValueError),
    ):
        t.move_to(angles, timeout_s=5.0)


def test_move_to_interlock_fault_mid_move_is_interlock_open() -> None:
    pairs = [
        *LIMIT_PAIRS,
        (state_q(3), state_r(READY)),
        (state_q(2), state_r(READY)),
        (state_q(1), state_r(READY)),
        (":DEMAND:POSITION 3,+010.00000", "OK"),
        (":DEMAND:POSITION 2,+000.00000", "OK"),
        (":DEMAND:POSITION 1,+000.00000", "OK"),
        (state_q(3), state_r(0x0002, mode="Off", interlock="Fault", pos=4.0)),
        (state_q(2), state_r(0, mode="Off", interlock="Fault")),
        (state_q(1), state_r(0, mode="Off", interlock="Fault")),
        (":SYSTEM:ERROR?", '309,"Interlock fault"'),
        NO_ERR,
    ]
    with expected_protocol(pairs) as t, pytest.raises(InterlockOpen, match="309,Interlock fault"):
        t.move_to((10.0, 0.0, 0.0), timeout_s=30.0)


def test_move_to_following_error_is_device_error() -> None:
    pairs = [
        *LIMIT_PAIRS,
        (state_q(3), state_r(READY)),
        (state_q(2), state_r(READY)),
        (state_q(1), state_r(READY)),
        (":DEMAND:POSITION 3,+000.00000", "OK"),
        (":DEMAND:POSITION 2,+010.00000", "OK"),
        (":DEMAND:POSITION 1,+000.00000", "OK"),
        (state_q(3), state_r(READY)),
        (state_q(2), state_r(0x0088, mode="Off")),
        (state_q(1), state_r(READY)),
        (":SYSTEM:ERROR?", '203,"Following error"'),
        NO_ERR,
    ]
    with expected_protocol(pairs) as t, pytest.raises(DeviceError, match="following error"):
        t.move_to((0.0, 10.0, 0.0), timeout_s=30.0)


def test_start_rate() -> None:
    pairs = [
        (":LIMIT:ABSOLUTE? 3", LIMITS),
        (state_q(3), state_r(READY)),
        (":MODE:RATE 3", "OK"),
        (":DEMAND:RATE 3,-015.00000", "OK"),
    ]
    with expected_protocol(pairs) as t:
        t.start_rate(1, -15.0)


def test_start_rate_above_limit_is_refused_locally() -> None:
    with expected_protocol([(":LIMIT:ABSOLUTE? 1", LIMITS)]) as t, pytest.raises(LimitError):
        t.start_rate(3, 250.0)


def test_start_oscillation() -> None:
    pairs = [
        (state_q(2), state_r(READY)),
        (":MODE:SYNTHESIS 2", "OK"),
        (":DEMAND:OSC 2,+002.50000,+000.25000,+000.00000", "OK"),
    ]
    with expected_protocol(pairs) as t:
        t.start_oscillation(2, 2.5, period_s=4.0)


def test_stop_is_stop_all() -> None:
    with expected_protocol([(":STOP ALL", "OK")]) as t:
        t.stop()


def test_make_safe_order() -> None:
    pairs = [
        (":STOP ALL", "OK"),
        (state_q(3), state_r(0x0008)),
        (state_q(2), state_r(0x0008)),
        (state_q(1), state_r(0x0008)),
        (":MODE:OFF ALL", "OK"),
        (":INTERLOCK:OPEN ALL", "OK"),
    ]
    with expected_protocol(pairs) as t:
        t.make_safe(timeout_s=5.0)


def test_make_safe_tries_every_step_and_raises_the_first_failure() -> None:
    pairs = [
        (":STOP ALL", DeviceTimeout("silent")),
        (state_q(3), DeviceTimeout("silent")),
        (":MODE:OFF ALL", "OK"),
        (":INTERLOCK:OPEN ALL", "OK"),
    ]
    with expected_protocol(pairs) as t, pytest.raises(DeviceTimeout, match="STOP ALL"):
        t.make_safe(timeout_s=5.0)


def test_prepare_resets_closes_and_selects_position_mode() -> None:
    pairs = [
        NO_ERR,
        (state_q(3), state_r(0, mode="Off", interlock="Fault")),
        (":INTERLOCK:RESET 3", "OK"),
        (":INTERLOCK:CLOSE 3", "OK"),
        (state_q(3), state_r(0x0008, mode="Off")),
        (":MODE:POSITION 3", "OK"),
        (state_q(2), state_r(READY)),
        (state_q(2), state_r(READY)),
        (state_q(1), state_r(0, mode="Off", interlock="Open")),
        (":INTERLOCK:CLOSE 1", "OK"),
        (state_q(1), state_r(0x0008, mode="Off")),
        (":MODE:POSITION 1", "OK"),
    ]
    with expected_protocol(pairs) as t:
        t.prepare()


@pytest.mark.parametrize(
    ("reply", "queue", "error"),
    [
        ('ERR -222,"Data out of range"', '-222,"Data out of range"', LimitError),
        ('ERR 107,"Software limit -"', '107,"Software limit -"', LimitError),
        ('ERR 309,"Interlock open"', '309,"Interlock open"', InterlockOpen),
        ('ERR 112,"E-stop latched"', '112,"E-stop latched"', InterlockOpen),
        ('ERR -221,"Settings conflict: axis moving"', '-221,"Settings conflict: axis moving"', DeviceError),
    ],
)
def test_err_reply_drains_the_queue_and_raises_typed(reply: str, queue: str, error: type[Exception]) -> None:
    pairs = [(":STOP ALL", reply), (":SYSTEM:ERROR?", queue), NO_ERR]
    with expected_protocol(pairs) as t, pytest.raises(error) as info:
        t.stop()
    assert queue.replace('"', "") in str(info.value)
    if error is DeviceError:
        assert info.value.code == -221  # type: ignore[attr-defined]


def test_garbled_reply_is_protocol_error_with_the_line() -> None:
    with expected_protocol([(":STOP ALL", "O\x8bK")]) as t, pytest.raises(ProtocolError) as info:
        t.stop()
    assert info.value.line == "O\x8bK"


def test_unexpected_reply_is_protocol_error() -> None:
    with expected_protocol([(":STOP ALL", "+000.00000")]) as t, pytest.raises(ProtocolError) as info:
        t.stop()
    assert info.value.line == "+000.00000"


def test_timeout_names_the_command() -> None:
    with (
        expected_protocol([(":STOP ALL", DeviceTimeout("no line"))]) as t,
        pytest.raises(DeviceTimeout, match="STOP ALL"),
    ):
        t.stop()
