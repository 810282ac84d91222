"""Line transport on ``serial.serial_for_url``: terminators, encoding, deadlines.

Any pyserial URL works: a device path or ``serial:///dev/ttyUSB0?baud=115200`` (a real
RS-232 port), ``socket://host:port`` (a serial-to-Ethernet converter or the simulated
controller), ``loop://`` (echo, for framing tests).

pyserial's timeouts are per read call, so ``readline`` can block far longer than its
timeout on a chatty line (pyserial#182, #487). :meth:`LineTransport.read_line` instead
takes an absolute deadline and re-arms the port timeout with what is left of it before
every read, so a call never outlives its deadline by more than one scheduler tick.
"""

from __future__ import annotations

import logging
import time
import urllib.parse

import serial

from drivers.errors import DeviceTimeout, LinkLost, ProtocolError

log = logging.getLogger(__name__)

TERMINATOR = b"\r\n"
DEFAULT_BAUD = 115200
MAX_LINE_BYTES = 4096


def split_serial_url(url: str) -> tuple[str, int]:
    """(pyserial port or URL, baud rate) for ``url``.

    ``serial:///dev/ttyS0?baud=9600`` -> (``/dev/ttyS0``, 9600); a plain path or any other
    pyserial URL (``socket://``, ``loop://``) passes through with the default baud rate.

    :raises ValueError: a ``serial://`` URL without a device path or with a bad baud rate.
    """
    parsed = urllib.parse.urlsplit(url)
    if parsed.scheme != "serial":
        return url, DEFAULT_BAUD
    path = parsed.path
    if not path:
        raise ValueError(f"serial URL without a device path: {url!r} (expected serial:///dev/ttyX)")
    query = urllib.parse.parse_qs(parsed.query)
    baud_text = query.get("baud", [str(DEFAULT_BAUD)])[-1]
    try:
        baud = int(baud_text)
    except ValueError:
        raise ValueError(f"serial URL {url!r}: baud must be an integer, got {baud_text!r}") from None
    if baud <= 0:
        raise ValueError(f"serial URL {url!r}: baud must be > 0, got {baud}")
    return path, baud


class LineTransport:
    """ASCII lines over a pyserial port, with a deadline per call.

    :param url: port path or pyserial URL (see :func:`split_serial_url`).
    :param terminator: line terminator written after, and expected after, every line.

    Not thread-safe by itself: the driver above holds one lock per command/reply pair.

    :raises LinkLost: the port cannot be opened.
    """

    def __init__(self, url: str, *, terminator: bytes = TERMINATOR) -> None:
        self.url = url
        self.terminator = terminator
        port, baud = split_serial_url(url)
        try:
            self._port = serial.serial_for_url(
                port, baudrate=baud, bytesize=8, parity="N", stopbits=1, timeout=0, write_timeout=5.0
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkLost(f"cannot open {url!r}: {exc}") from exc
        self._buffer = bytearray()

    @property
    def is_open(self) -> bool:
        return bool(self._port.is_open)

    def write_line(self, line: str, deadline: float) -> None:
        """Send ``line`` plus the terminator; ``deadline`` is a ``time.monotonic()`` value.

        :raises ValueError: ``line`` not ASCII or holding the terminator.
        :raises LinkLost: the port is closed or the peer went away.
        :raises DeviceTimeout: the output did not drain before the deadline.
        """
        data = line.encode("ascii")
        if self.terminator in data or b"\n" in data or b"\r" in data:
            raise ValueError(f"line holds a line break: {line!r}")
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise DeviceTimeout(f"{self.url}: no time left to send {line!r}")
        try:
            self._port.write_timeout = remaining
            self._port.write(data + self.terminator)
            self._port.flush()
        except serial.SerialTimeoutException as exc:
            raise DeviceTimeout(f"{self.url}: sending {line!r} did not finish in time") from exc
        except (serial.SerialException, OSError) as exc:
            raise LinkLost(f"{self.url}: link lost while sending {line!r}: {exc}") from exc

    def read_line(self, deadline: float) -> str:
        """One reply line without its terminator, by ``deadline`` (``time.monotonic()``).

        :raises DeviceTimeout: no complete line before the deadline (partial bytes are kept
            in the message and dropped from the buffer).
        :raises LinkLost: the port closed or the peer disconnected.
        :raises ProtocolError: the line is not ASCII or exceeds ``MAX_LINE_BYTES``.
        """
        while True:
            end = self._buffer.find(self.terminator)
            if end >= 0:
                raw = bytes(self._buffer[:end])
                del self._buffer[: end + len(self.terminator)]
                try:
                    return raw.decode("ascii")
                except UnicodeDecodeError:
                    raise ProtocolError(f"{self.url}: reply is not ASCII", raw) from None
            if len(self._buffer) > MAX_LINE_BYTES:
                raw = bytes(self._buffer)
                self._buffer.clear()
                raise ProtocolError(f"{self.url}: no terminator within {MAX_LINE_BYTES} bytes", raw)
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                partial = bytes(self._buffer)
                self._buffer.clear()
                detail = f" (partial reply {partial!r} dropped)" if partial else ""
                raise DeviceTimeout(f"{self.url}: no reply line before the deadline{detail}")
            self._buffer += self._read_some(remaining)

    def _read_some(self, remaining_s: float) -> bytes:
        try:
            self._port.timeout = remaining_s
            first: bytes = self._port.read(1)  # pyserial is untyped: read() returns bytes
            if not first:
                return b""
            self._port.timeout = 0
            rest: bytes = self._port.read(MAX_LINE_BYTES)
            return first + rest
        except (serial.SerialException, OSError) as exc:
            raise LinkLost(f"{self.url}: link lost while reading: {exc}") from exc
        except (TypeError, AttributeError) as exc:
            # pyserial's POSIX backend raises these when the port was closed under it.
            raise LinkLost(f"{self.url}: port closed while reading: {exc}") from exc

    def discard_input(self) -> bytes:
        """Drop anything already received (a late reply to a timed-out command); returns it."""
        stale = bytes(self._buffer)
        self._buffer.clear()
        try:
            self._port.timeout = 0
            late: bytes = self._port.read(MAX_LINE_BYTES)  # pyserial is untyped
            stale += late
        except (serial.SerialException, OSError) as exc:
            raise LinkLost(f"{self.url}: link lost: {exc}") from exc
        if stale:
            log.warning("%s: discarded stale input %r", self.url, stale)
        return stale

    def query(self, line: str, timeout_s: float) -> str:
        """Send ``line`` and return the one reply line, all within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        self.discard_input()
        self.write_line(line, deadline)
        return self.read_line(deadline)

    def close(self) -> None:
        """Close the port (idempotent)."""
        try:
            self._port.close()
        except (serial.SerialException, OSError) as exc:
            log.warning("%s: error while closing: %s", self.url, exc)
