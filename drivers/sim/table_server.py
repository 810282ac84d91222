"""Serves the table's text protocol over TCP and over a pseudo-terminal.

Both run on background threads; the real driver connects with ``socket://127.0.0.1:PORT``
or with the pty's device path (``/dev/pts/N``, or ``serial:///dev/pts/N``). Every line
goes through :class:`~drivers.sim.table_commands.CommandSet`; the ``no_reply`` and
``garbled`` faults of the controller are applied here, on the wire.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import select
import socket
import threading
import time
import tty
from collections.abc import Callable

from drivers.sim.table_commands import CommandSet
from drivers.sim.table_controller import TableController
from drivers.sim.table_grammar import format_error
from drivers.table_protocol import MAX_LINE_CHARS, ScpiError

log = logging.getLogger(__name__)

POLL_S = 0.05
"""How often the serving threads look at the stop flag (wall s)."""


class TableServer:
    """The simulated controller's serial/TCP front end.

    :param controller: the controller to serve.
    :param latency_s: wall seconds between reading a command and answering it (a real
        controller takes ~10 ms; 0 for fast tests).
    """

    def __init__(self, controller: TableController, *, latency_s: float = 0.0) -> None:
        if latency_s < 0:
            raise ValueError(f"latency_s must be >= 0, got {latency_s!r}")
        self.controller = controller
        self.latency_s = latency_s
        self.commands = CommandSet(controller)
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._sockets: list[socket.socket] = []
        self._fds: list[int] = []
        self._lock = threading.Lock()

    # ---- line handling -----------------------------------------------------------------
    def handle_line(self, line: bytes) -> bytes | None:
        """Reply bytes (with terminator) for one received line, ``None`` for no reply."""
        if self.controller.fault("no_reply") is not None:
            return None
        try:
            text = line.decode("ascii")
        except UnicodeDecodeError:
            self.controller.push_error(ScpiError.SYNTAX, "Syntax error")
            reply = format_error(ScpiError.SYNTAX, "Syntax error")
        else:
            reply = self.commands.execute(text)
        if self.latency_s:
            time.sleep(self.latency_s)
        data = reply.encode("ascii")
        garbled = self.controller.fault("garbled")
        if garbled is not None and self.controller.rng.random() < garbled["probability"]:
            data = self._garble(data)
        return data + b"\r\n"

    def _garble(self, data: bytes) -> bytes:
        """Replace 1–3 characters with bytes outside printable ASCII (never CR or LF)."""
        rng = self.controller.rng
        out = bytearray(data or b"?")
        for _ in range(rng.randint(1, 3)):
            bad = rng.choice([*range(0x01, 0x0A), 0x0B, 0x0C, *range(0x0E, 0x20), *range(0x80, 0x100)])
            out[rng.randrange(len(out))] = bad
        return bytes(out)

    def _serve_stream(
        self, read: Callable[[], bytes | None], write: Callable[[bytes], None], name: str
    ) -> None:
        """Read lines until EOF or close(); answer each."""
        buffer = bytearray()
        while not self._stop.is_set():
            try:
                chunk = read()
            except OSError:
                break
            if chunk is None:
                continue
            if not chunk:
                break
            buffer += chunk
            while True:
                end = buffer.find(b"\n")
                if end < 0:
                    if len(buffer) > MAX_LINE_CHARS:
                        buffer.clear()
                        self.controller.push_error(ScpiError.SYNTAX, "Syntax error")
                        self._write(
                            write,
                            format_error(ScpiError.SYNTAX, "Syntax error: line too long").encode() + b"\r\n",
                        )
                    break
                line = bytes(buffer[:end]).rstrip(b"\r")
                del buffer[: end + 1]
                reply = self.handle_line(line)
                if reply is not None and not self._write(write, reply):
                    return
        log.debug("%s: connection closed", name)

    @staticmethod
    def _write(write: Callable[[bytes], None], data: bytes) -> bool:
        try:
            write(data)
            return True
        except OSError:
            return False

    def _start(self, target: Callable[[], None], name: str) -> None:
        thread = threading.Thread(target=target, name=name, daemon=True)
        with self._lock:
            self._threads.append(thread)
        thread.start()

    # ---- TCP ---------------------------------------------------------------------------
    def serve_tcp(self, host: str = "127.0.0.1", port: int = 0) -> str:
        """Listen on ``host:port`` (0 = a free port); returns ``socket://host:PORT``."""
        listener = socket.create_server((host, port))
        listener.settimeout(POLL_S)
        with self._lock:
            self._sockets.append(listener)
        bound_port = listener.getsockname()[1]
        self._start(lambda: self._accept_loop(listener), f"table-tcp-{bound_port}")
        return f"socket://{host}:{bound_port}"

    def _accept_loop(self, listener: socket.socket) -> None:
        while not self._stop.is_set():
            try:
                conn, peer = listener.accept()
            except TimeoutError:
                continue
            except OSError:
                break
            conn.settimeout(POLL_S)
            with self._lock:
                self._sockets.append(conn)
            self._start(functools.partial(self._serve_socket, conn, peer), f"table-conn-{peer[1]}")

    def _serve_socket(self, conn: socket.socket, peer: object) -> None:
        def read() -> bytes | None:
            try:
                return conn.recv(4096)
            except TimeoutError:
                return None

        def write(data: bytes) -> None:
            conn.settimeout(5.0)
            try:
                conn.sendall(data)
            finally:
                conn.settimeout(POLL_S)

        try:
            self._serve_stream(read, write, f"tcp {peer}")
        finally:
            with contextlib.suppress(OSError):
                conn.close()

    # ---- pseudo-terminal ---------------------------------------------------------------
    def serve_pty(self) -> str:
        """Open a pseudo-terminal and serve on its master side; returns the slave's path."""
        master, slave = os.openpty()
        tty.setraw(slave)
        path = os.ttyname(slave)
        with self._lock:
            self._fds += [master, slave]  # the slave stays open so the pty outlives clients

        def read() -> bytes | None:
            ready, _, _ = select.select([master], [], [], POLL_S)
            return os.read(master, 4096) if ready else None

        def write(data: bytes) -> None:
            os.write(master, data)

        self._start(lambda: self._serve_stream(read, write, f"pty {path}"), f"table-pty-{path}")
        return path

    def drop_connections(self) -> int:
        """Cut every client connection (a lost line: the client sees the link drop) and keep
        listening; the number cut."""
        with self._lock:
            conns = [s for s in self._sockets if not _is_listener(s)]
        cut = 0
        for s in conns:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
                cut += 1
        return cut

    # ---- lifetime ----------------------------------------------------------------------
    def close(self) -> None:
        """Stop serving: close the listeners, the connections and the pty (clients see the link drop)."""
        self._stop.set()
        with self._lock:
            sockets, fds, threads = list(self._sockets), list(self._fds), list(self._threads)
            self._sockets.clear()
            self._fds.clear()
        for s in sockets:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            with contextlib.suppress(OSError):
                s.close()
        for t in threads:
            if t is not threading.current_thread():
                t.join(timeout=2.0)
        for fd in fds:
            with contextlib.suppress(OSError):
                os.close(fd)

    def __enter__(self) -> TableServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _is_listener(sock: socket.socket) -> bool:
    try:
        return bool(sock.getsockopt(socket.SOL_SOCKET, socket.SO_ACCEPTCONN))
    except OSError:
        return False
