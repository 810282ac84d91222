"""A client that sends its request headers slowly (one byte a second: "slowloris") is answered
408 and cut off after :data:`api.slow_clients.HEADER_READ_TIMEOUT_S`, on a real uvicorn server
with the protocol ``calbench serve`` uses; normal and keep-alive requests are unaffected."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
import uvicorn

from api.slow_clients import HEADER_READ_TIMEOUT_S, PROTOCOL

pytestmark = pytest.mark.timeout(60)


async def hello(scope: dict[str, Any], receive: Any, send: Any) -> None:
    if scope["type"] != "http":
        return
    await send({"type": "http.response.start", "status": 200, "headers": [(b"content-length", b"2")]})
    await send({"type": "http.response.body", "body": b"ok"})


@pytest.fixture()
def port() -> Iterator[int]:
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    config = uvicorn.Config(hello, http=PROTOCOL, log_level="warning", lifespan="off")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    deadline = time.monotonic() + 10
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.05)
    assert server.started
    try:
        yield int(sock.getsockname()[1])
    finally:
        server.should_exit = True
        thread.join(10)
        sock.close()


def _read_all(conn: socket.socket, timeout_s: float) -> bytes:
    conn.settimeout(timeout_s)
    out = b""
    while chunk := conn.recv(4096):
        out += chunk
    return out


def test_headers_sent_one_byte_a_second_are_cut_off(port: int) -> None:
    request = b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: " + b"a" * 100 + b"\r\n\r\n"
    t0 = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=5) as conn:
        sent = 0
        try:
            for byte in request:  # 1 byte/s: the whole request would take > 2 minutes
                conn.sendall(bytes([byte]))
                sent += 1
                if time.monotonic() - t0 > 3 * HEADER_READ_TIMEOUT_S:
                    break
                conn.settimeout(1.0)
                try:
                    reply = conn.recv(4096)
                except TimeoutError:
                    continue
                break  # the server answered (or closed: b"") before the headers were complete
        except (BrokenPipeError, ConnectionResetError):
            reply = b""
        elapsed_s = time.monotonic() - t0
        rest = b"" if not reply else _read_all(conn, 5.0)
    assert sent < len(request)
    assert HEADER_READ_TIMEOUT_S - 1.0 <= elapsed_s <= HEADER_READ_TIMEOUT_S + 3.0, elapsed_s
    assert (reply + rest).startswith(b"HTTP/1.1 408 "), reply + rest


def test_a_silent_connection_is_cut_off_too(port: int) -> None:
    t0 = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=5) as conn:
        reply = _read_all(conn, 3 * HEADER_READ_TIMEOUT_S)
    assert reply.startswith(b"HTTP/1.1 408 ")
    assert time.monotonic() - t0 <= HEADER_READ_TIMEOUT_S + 3.0


def test_normal_and_keep_alive_requests_are_served(port: int) -> None:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as conn:
        for _ in range(2):  # the second request on the same connection, 2 s apart
            conn.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            reply = b""
            while not reply.endswith(b"ok"):
                reply += conn.recv(4096)
            assert reply.startswith(b"HTTP/1.1 200 "), reply
            time.sleep(2.0)
