"""The real driver against the simulated controller, over TCP and over a pseudo-terminal.

The simulated clock runs ×50, so moves of a few simulated seconds take tens of wall
milliseconds. Nothing asserts a wall duration; hangs are caught by pytest-timeout.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest

from drivers.base import AxisMode, RotaryTable
from drivers.errors import DeviceError, DeviceTimeout, InterlockOpen, LimitError, LinkLost, ProtocolError
from drivers.sim.clock import SimClock
from drivers.sim.table_axis import AxisLimits
from drivers.sim.table_controller import TableController
from drivers.sim.table_server import TableServer
from drivers.table import SerialRotaryTable

pytestmark = pytest.mark.timeout(60)

SPEED = 50.0


@dataclass
class Bench:
    clock: SimClock
    ctl: TableController
    server: TableServer
    table: SerialRotaryTable
    url: str


@pytest.fixture(params=["tcp", "pty"])
def bench(request: pytest.FixtureRequest) -> Iterator[Bench]:
    clock = SimClock(speed=SPEED)
    limits = [AxisLimits(), AxisLimits(pos_lo_deg=-100.0, pos_hi_deg=100.0), AxisLimits()]
    ctl = TableController(clock, limits=limits)
    server = TableServer(ctl)
    url = server.serve_tcp() if request.param == "tcp" else server.serve_pty()
    table = SerialRotaryTable(url, timeout_s=0.5, poll_interval_s=0.005)
    try:
        yield Bench(clock, ctl, server, table, url)
    finally:
        table.close()
        server.close()


def wait_for(condition: object, what: str, polls: int = 2000) -> None:
    for _ in range(polls):
        if condition():  # type: ignore[operator]
            return
        time.sleep(0.002)
    raise AssertionError(f"never happened: {what}")


def test_driver_satisfies_the_protocol(bench: Bench) -> None:
    assert isinstance(bench.table, RotaryTable)
    assert bench.table.identify().startswith("SIMTABLE,")


def test_move_reaches_target_and_reports_in_position(bench: Bench) -> None:
    t = bench.table
    t.prepare()
    t.move_to((30.0, -90.0, 200.0), timeout_s=20.0)  # 200 deg is -160 deg on the wire
    assert t.positions_deg() == pytest.approx((30.0, -90.0, -160.0), abs=1e-5)
    status = t.status()
    assert all(a.in_position and a.mode is AxisMode.POSITION for a in status.axes)
    assert status.interlock_ok and not status.estop and status.errors == ()
    true = np.degrees(bench.ctl.kinematics(np.array([bench.clock.now_s()])).angles_rad[0])
    assert true == pytest.approx([30.0, -90.0, -160.0], abs=1e-9)


def test_rate_mode(bench: Bench) -> None:
    t = bench.table
    t.prepare()
    t.start_rate(1, 25.0)
    wait_for(lambda: t.rates_deg_s()[0] == pytest.approx(25.0, abs=1e-5), "rate reached")
    assert t.status().axes[0].mode is AxisMode.RATE
    t.stop()
    t.wait_until_stopped(timeout_s=10.0)
    assert t.rates_deg_s() == (0.0, 0.0, 0.0)


def test_oscillation_mode(bench: Bench) -> None:
    t = bench.table
    t.prepare()
    t.move_to((0.0, 10.0, 0.0), timeout_s=20.0)
    t0 = bench.clock.now_s()
    t.start_oscillation(2, amplitude_deg=2.0, period_s=1.0)
    bench.clock.sleep(6.0)
    # After the 2-period ramp the axis swings 10 ± 2 deg, one period per second.
    times = np.linspace(t0 + 2.5, t0 + 5.5, 3001)
    angle = np.degrees(bench.ctl.kinematics(times).angles_rad[:, 1])
    assert angle.max() == pytest.approx(12.0, abs=0.01)
    assert angle.min() == pytest.approx(8.0, abs=0.01)
    spectrum = np.abs(np.fft.rfft(angle[:-1] - angle.mean()))
    assert np.fft.rfftfreq(3000, d=1e-3)[np.argmax(spectrum)] == pytest.approx(1.0, abs=0.34)


def test_limits_raise_limit_error(bench: Bench) -> None:
    t = bench.table
    t.prepare()
    with pytest.raises(LimitError, match="axis 2"):
        t.move_to((0.0, 150.0, 0.0), timeout_s=5.0)  # refused before anything moves
    with pytest.raises(LimitError, match="206"):
        t.command(":DEMAND:POSITION 2,+150.00000")  # the controller refuses it too
    with pytest.raises(LimitError):
        t.start_rate(1, 500.0)
    assert t.errors() == ()  # the refusal's queue entry was drained with it


def test_interlock_trip_mid_move_raises_interlock_open(bench: Bench) -> None:
    t = bench.table
    t.prepare()
    bench.ctl.inject("interlock_trip", after_s=0.5)
    with pytest.raises(InterlockOpen, match="Interlock fault"):
        t.move_to((170.0, 0.0, 0.0), timeout_s=20.0)
    status = t.status()
    assert not status.interlock_ok
    assert all(a.fault == "interlock fault" and a.mode is AxisMode.OFF for a in status.axes)
    t.prepare()  # reset, close, position mode: usable again
    t.move_to((0.0, 0.0, 0.0), timeout_s=20.0)


def test_no_reply_is_device_timeout_within_the_deadline(bench: Bench) -> None:
    t = bench.table
    t.prepare()
    bench.ctl.inject("no_reply")
    with pytest.raises(DeviceTimeout, match="READ:POSITION"):
        t.positions_deg()
    with pytest.raises(DeviceTimeout):
        t.move_to((10.0, 0.0, 0.0), timeout_s=2.0)
    bench.ctl.clear("no_reply")
    assert t.identify().startswith("SIMTABLE")


def test_garbled_reply_is_protocol_error_with_the_line(bench: Bench) -> None:
    t = bench.table
    bench.ctl.inject("garbled")
    with pytest.raises(ProtocolError) as info:
        t.identify()
    assert info.value.line is not None and len(info.value.line) > 0
    bench.ctl.clear("garbled")
    assert t.identify() == "SIMTABLE,3AX-100,SN0001,FW2.3"


def test_server_gone_is_link_lost(bench: Bench) -> None:
    t = bench.table
    assert t.identify()
    bench.server.close()
    with pytest.raises(LinkLost):
        for _ in range(3):  # the first write may still land in a kernel buffer
            t.positions_deg()


def test_stalled_axis_is_a_device_error_before_the_timeout(bench: Bench) -> None:
    t = bench.table
    t.prepare()
    bench.ctl.inject("stalled_axis", axis=3, trip_s=1.0)
    with pytest.raises(DeviceError, match="following error"):
        t.move_to((0.0, 0.0, 45.0), timeout_s=30.0)


def test_slow_settle_delays_in_position(bench: Bench) -> None:
    t = bench.table
    t.prepare()
    bench.ctl.inject("slow_settle", peak_deg=0.05, frequency_hz=2.0, decay_s=1.0)
    start = bench.clock.now_s()
    t.move_to((90.0, 0.0, 0.0), timeout_s=30.0)
    elapsed_sim = bench.clock.now_s() - start
    # move 2·sqrt(90/200) s, ring inside 0.001 deg after 5.75·decay, settle 0.5 s
    assert elapsed_sim >= 2 * math.sqrt(90 / 200) + 5.7 + 0.5


def test_make_safe_leaves_the_table_off_and_open(bench: Bench) -> None:
    t = bench.table
    t.prepare()
    t.start_rate(1, 50.0)
    t.make_safe(timeout_s=10.0)
    status = t.status()
    assert all(a.mode is AxisMode.OFF and a.rate_deg_s == 0.0 for a in status.axes)
    assert not status.interlock_ok
