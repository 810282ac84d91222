"""Line transport deadlines and URL handling, and open_table's URL dispatch."""

from __future__ import annotations

import socket

import pytest

from drivers.errors import DeviceTimeout, LinkLost, ProtocolError
from drivers.factory import open_table
from drivers.sim.clock import SimClock
from drivers.sim.table_controller import TableController
from drivers.sim.table_server import TableServer
from drivers.transport import LineTransport, split_serial_url

pytestmark = pytest.mark.timeout(30)


def test_split_serial_url() -> None:
    assert split_serial_url("serial:///dev/ttyS0?baud=9600") == ("/dev/ttyS0", 9600)
    assert split_serial_url("serial:///dev/ttyUSB1") == ("/dev/ttyUSB1", 115200)
    assert split_serial_url("socket://127.0.0.1:9888") == ("socket://127.0.0.1:9888", 115200)
    for bad in ("serial://", "serial:///dev/ttyS0?baud=fast", "serial:///dev/ttyS0?baud=0"):
        with pytest.raises(ValueError):
            split_serial_url(bad)


def test_loop_framing_and_deadline() -> None:
    t = LineTransport("loop://")
    try:
        assert t.query(":STATUS? 1", timeout_s=1.0) == ":STATUS? 1"  # the loop echoes
        with pytest.raises(DeviceTimeout, match="no reply line"):
            t.read_line(deadline=0.0)
        with pytest.raises(ValueError, match="line break"):
            t.query("a\r\nb", timeout_s=1.0)
    finally:
        t.close()


def test_partial_line_is_dropped_and_reported_on_timeout() -> None:
    import time

    t = LineTransport("loop://")
    try:
        t._port.write(b"+090.0")  # a reply cut short
        with pytest.raises(DeviceTimeout, match="partial reply"):
            t.read_line(deadline=time.monotonic() + 0.2)
    finally:
        t.close()


def test_non_ascii_reply_is_protocol_error_with_bytes() -> None:
    import time

    t = LineTransport("loop://")
    try:
        t._port.write(b"O\xffK\r\n")
        with pytest.raises(ProtocolError) as info:
            t.read_line(deadline=time.monotonic() + 1.0)
        assert info.value.line == b"O\xffK"
    finally:
        t.close()


def test_open_table_over_tcp_checks_the_link() -> None:
    with TableServer(TableController(SimClock(speed=50.0))) as server:
        table = open_table(server.serve_tcp(), timeout_s=0.5)
        try:
            assert table.n_axes == 3
            assert table.positions_deg() == (0.0, 0.0, 0.0)
        finally:
            table.close()


def test_open_table_silent_device_is_device_timeout() -> None:
    ctl = TableController(SimClock())
    ctl.inject("no_reply")
    with TableServer(ctl) as server, pytest.raises(DeviceTimeout):
        open_table(server.serve_pty(), timeout_s=0.3)


def test_open_table_refused_connection_is_link_lost() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # bound, not listening: connect is refused
        with pytest.raises(LinkLost, match=str(port)):
            open_table(f"socket://127.0.0.1:{port}", timeout_s=0.3)


def test_open_table_echo_port_is_protocol_error() -> None:
    with pytest.raises(ProtocolError):
        open_table("loop://", timeout_s=0.3)


def test_open_table_unknown_scheme() -> None:
    with pytest.raises(ValueError, match="unsupported table URL"):
        open_table("ftp://table")
