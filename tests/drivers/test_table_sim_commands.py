"""The simulated controller's side of the protocol: every command and reply as message pairs.

A hand-driven clock makes the replies exact; expected values are worked out by hand from
the trapezoid / ramp / sinusoid formulas with the default limits (200 deg/s, 200 deg/s²,
settle 0.5 s).
"""

from __future__ import annotations

import math

import pytest

from drivers import table_protocol as tp
from drivers.base import AxisMode
from drivers.sim.table_commands import CommandSet
from drivers.sim.table_controller import TableController
from drivers.sim.table_grammar import parse_command_line, short_form

from .table_fakes import ManualClock

Pair = tuple[str, str]


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock()


@pytest.fixture
def cs(clock: ManualClock) -> CommandSet:
    return CommandSet(TableController(clock))  # type: ignore[arg-type]


def run(cs: CommandSet, pairs: list[Pair]) -> None:
    for line, reply in pairs:
        assert cs.execute(line) == reply, line


def test_identity_reset_and_interlocks(cs: CommandSet) -> None:
    run(
        cs,
        [
            ("*IDN?", "SIMTABLE,3AX-100,SN0001,FW2.3"),
            ("*RST", "OK"),
            (":INTERLOCK? 1", "Open"),
            (":MODE:POSITION 1", 'ERR 109,"Interlock open"'),
            (":SYSTEM:ERROR?", '109,"Interlock open"'),
            (":SYST:ERR?", '0,"No error"'),
            (":INT:CLOS ALL", "OK"),
            (":INTERLOCK? 3", "Closed"),
            (":INTERLOCK:OPEN 2", "OK"),
            (":INTERLOCK? 2", "Open"),
            (":INTERLOCK? 1", "Closed"),
            (":STATUS? 2", "0000"),
            (":STATUS? 1", "0008"),
        ],
    )


def test_position_move_trapezoid(cs: CommandSet, clock: ManualClock) -> None:
    # 90 deg at a = 200 deg/s², v = 200 deg/s: triangular, T = 2·sqrt(90/200) = 1.341641 s.
    t_move = 2 * math.sqrt(90 / 200)
    run(
        cs,
        [
            (":INTERLOCK:CLOSE ALL", "OK"),
            (":MODE? 3", "Off"),
            (":MODE:POS ALL", "OK"),
            (":MODE? 3", "Position"),
            (":STAT? 3", "0009"),
            (":DEMAND:POSITION 3,+090.00000", "OK"),
            (":STAT? 3", "000A"),
        ],
    )
    clock.advance(t_move / 4)  # accelerating: ½·200·(T/4)² = 11.25 deg, 200·T/4 = 67.08204 deg/s
    run(cs, [(":READ:POS? 3;RATE? 3;:READ:ACC? 3", "+011.25000;+067.08204;+200.00000")])
    clock.advance(t_move / 2)  # decelerating, symmetric: 90 − 11.25 deg
    run(cs, [(":READ:POS? 3;RATE? 3;ACC? 3", "+078.75000;+067.08204;-200.00000")])
    clock.advance(t_move / 4 + 0.25)  # arrived, but not yet settled for 0.5 s
    run(cs, [(":READ:POSITION? 3", "+090.00000"), (":STATUS? 3", "0008")])
    clock.advance(0.26)
    run(cs, [(":STATUS? 3", "0009"), (":READ:POS? 1", "+000.00000")])


def test_delta_and_wrap_take_the_short_way(cs: CommandSet, clock: ManualClock) -> None:
    run(
        cs,
        [(":INTERLOCK:CLOSE ALL", "OK"), (":MODE:POSITION 1", "OK"), (":DEMAND:POSITION 1,+170.00000", "OK")],
    )
    clock.advance(10)
    run(cs, [(":DEM:DELT 1,+020.00000", "OK")])
    clock.advance(10)
    run(
        cs,
        [
            (":READ:POS? 1", "-170.00000"),
            (":DEMAND:DELTA 1,+190.00000", 'ERR -222,"Data out of range: |delta| > 180"'),
        ],
    )


def test_rate_mode_ramp(cs: CommandSet, clock: ManualClock) -> None:
    run(
        cs,
        [
            (":INTERLOCK:CLOSE 1", "OK"),
            (":MODE:RATE 1", "OK"),
            (":DEM:RATE 1,+010.00000", "OK"),
            (":STATUS? 1", "000A"),
        ],
    )
    clock.advance(1.0)  # ramp 10/200 = 0.05 s; angle = 10·1 − 10²/(2·200) = 9.75 deg
    run(
        cs,
        [
            (":READ:RATE? 1", "+010.00000"),
            (":READ:POSITION? 1", "+009.75000"),
            (":STATUS? 1", "000E"),
            (":MODE:POSITION 1", 'ERR -221,"Settings conflict: axis moving"'),
            (":STOP 1", "OK"),
        ],
    )
    clock.advance(0.05)
    run(
        cs,
        [
            (":READ:RATE? 1", "+000.00000"),
            (":STATUS? 1", "000C"),
            (":MODE? 1", "Rate"),
            (":READ:POSITION? 1", "+010.00000"),
            (":MODE:POSITION 1", "OK"),
        ],
    )


def test_synthesis_mode_oscillation(cs: CommandSet, clock: ManualClock) -> None:
    run(
        cs,
        [
            (":INTERLOCK:CLOSE 2", "OK"),
            (":MODE:SYNT 2", "OK"),
            (":DEMAND:OSC 2,+001.00000,+000.50000,+000.00000", "OK"),
            (":STAT? 2", "000A"),
        ],
    )
    clock.advance(4.5)  # after the 2-period ramp: sin(2π·0.5·4.5) = 1, cos = 0
    run(cs, [(":READ:POS? 2;RATE? 2;ACC? 2", f"+001.00000;+000.00000;{tp.format_number(-(math.pi**2))}")])


def test_limits(cs: CommandSet) -> None:
    run(
        cs,
        [
            (":LIMIT:ABSOLUTE? 1", "+200.00000,+200.00000,+000.00000,-180.00000,+180.00000,+220.00000"),
            (":LIMIT:RATE POSITION,1,+050.00000", "OK"),
            (":LIM:ACC POS,1,+500.00000", 'ERR -222,"Data out of range: acc limit"'),
            (":INTERLOCK:CLOSE 1", "OK"),
            (":MODE:RATE 1", "OK"),
            (":DEMAND:RATE 1,+250.00000", 'ERR -222,"Data out of range: rate above limit"'),
            (":DEMAND:POSITION 1,+010.00000", 'ERR -221,"Settings conflict: axis not in POSITION mode"'),
        ],
    )


def test_software_limits_of_a_limited_axis(clock: ManualClock) -> None:
    from drivers.sim.table_axis import AxisLimits

    ctl = TableController(
        clock, limits=[AxisLimits(), AxisLimits(pos_lo_deg=-100, pos_hi_deg=100), AxisLimits()]
    )  # type: ignore[arg-type]
    cs = CommandSet(ctl)
    run(
        cs,
        [
            (":INTERLOCK:CLOSE ALL", "OK"),
            (":MODE:POSITION 2", "OK"),
            (":DEMAND:POSITION 2,+120.00000", 'ERR 206,"Software limit +"'),
            (":DEMAND:POSITION 2,-120.00000", 'ERR 207,"Software limit -"'),
            (":MODE:RATE 2", 'ERR -221,"Settings conflict: limited-travel axis"'),
        ],
    )


def test_estop_latches(cs: CommandSet) -> None:
    run(
        cs,
        [
            (":INTERLOCK:CLOSE ALL", "OK"),
            (":ESTOP", "OK"),
            (":STATUS? 1", "0010"),
            (":INTERLOCK? 1", "Open"),
            (":INTERLOCK:CLOSE 1", 'ERR -221,"Settings conflict: E-stop latched"'),
            (":ESTOP:RESET", "OK"),
            (":INTERLOCK:CLOSE 1", "OK"),
            (":STATUS? 1", "0008"),
        ],
    )


@pytest.mark.parametrize(
    ("line", "reply"),
    [
        (":FOO 1", 'ERR -113,"Undefined header"'),
        (":STOP?", 'ERR -113,"Undefined header"'),
        (":STATUS? 4", 'ERR -222,"Data out of range: axis 4"'),
        (":STATUS?", 'ERR -109,"Missing parameter"'),
        (":STATUS? 1,2", 'ERR -108,"Parameter not allowed"'),
        (":STATUS? x", 'ERR -104,"Data type error: axis"'),
        (":MODE:POSITION 1;;", 'ERR -102,"Syntax error"'),
        (":DEMAND:RATE 1,nan", 'ERR -104,"Data type error: nan"'),
        ("*IDN? 1", 'ERR -108,"Parameter not allowed"'),
    ],
)
def test_bad_commands(cs: CommandSet, line: str, reply: str) -> None:
    code = reply.split()[1].split(",")[0]
    run(
        cs,
        [
            (line, reply),
            (":SYSTEM:ERROR?", f"{code},{reply.split(',', 1)[1]}"),
            (":SYSTEM:ERROR?", '0,"No error"'),
        ],
    )


def test_error_queue_overflow(cs: CommandSet) -> None:
    for _ in range(12):
        cs.execute(":FOO")
    replies = [cs.execute(":SYSTEM:ERROR?") for _ in range(11)]
    assert replies[:9] == ['-113,"Undefined header"'] * 9
    assert replies[9:] == ['-350,"Queue overflow"', '0,"No error"']


def test_short_forms_follow_the_scpi_rule() -> None:
    assert [
        short_form(k)
        for k in (
            "DEMAND",
            "POSITION",
            "SYSTEM",
            "ERROR",
            "INTERLOCK",
            "ACCELERATION",
            "OSCILLATION",
            "STATUS",
            "LIMIT",
            "RATE",
        )
    ] == ["DEM", "POS", "SYST", "ERR", "INT", "ACC", "OSC", "STAT", "LIM", "RATE"]
    assert parse_command_line(":read:pos? 1;RATE? 2;:stat? 3")[1].header == ("READ", "RATE")


def test_every_host_encoder_is_understood_by_the_controller(cs: CommandSet) -> None:
    """Each line the driver can send parses and runs (no -1xx grammar error)."""
    lines = [
        tp.IDN_QUERY,
        tp.ERROR_QUERY,
        tp.interlock("CLOSE", None),
        tp.interlock("RESET", 1),
        tp.interlock("OPEN", 2),
        tp.interlock("CLOSE", 2),
        tp.interlock_query(1),
        tp.mode_query(1),
        tp.mode(AxisMode.POSITION, 1),
        tp.demand_position(1, 5.0),
        tp.demand_delta(1, 5.0),
        tp.mode(AxisMode.RATE, 2),
        tp.demand_rate(2, 5.0),
        tp.mode(AxisMode.OSCILLATION, 3),
        tp.demand_oscillation(3, 1.0, 0.5),
        tp.read_query("position", [3, 2, 1]),
        tp.read_query("rate", [1]),
        tp.read_query("acc", [1, 2]),
        tp.status_query(1),
        tp.axis_state_query(2),
        tp.limit_rate(AxisMode.POSITION, 1, 10.0),
        tp.limit_acc(AxisMode.OSCILLATION, 1, 10.0),
        tp.limit_absolute_query(3),
        tp.stop(None),
        tp.stop(1),
        tp.mode(AxisMode.OFF, None),
        tp.ESTOP,
        tp.ESTOP_RESET,
        tp.RESET,
    ]
    for line in lines:
        reply = cs.execute(line)
        assert not tp.is_error(reply), (line, reply)
    assert tp.parse_axis_state(cs.execute(tp.axis_state_query(1))).mode is AxisMode.OFF
