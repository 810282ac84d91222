"""Open devices from URLs (the settings hold URLs, never driver classes).

Table URLs:

* ``serial:///dev/ttyUSB0?baud=115200`` — a real RS-232 port (default 115200 8N1);
* ``/dev/ttyUSB0`` or ``/dev/pts/N`` — the same, as a bare device path;
* ``socket://host:port`` — a serial-to-Ethernet converter, or the simulated controller
  (``drivers.sim.table_server``);
* ``loop://`` — pyserial's echo port (framing tests only: it answers every command with
  the command itself, which the driver rejects as a protocol error).

Each scheme maps to an opener in ``TABLE_OPENERS``; a new scheme (``sim://``) is one
more entry.
"""

from __future__ import annotations

import urllib.parse
from collections.abc import Callable

from drivers.base import RotaryTable
from drivers.errors import DriverError
from drivers.table import SerialRotaryTable

TableOpener = Callable[[str, float, int], RotaryTable]


def _open_serial_table(url: str, timeout_s: float, n_axes: int) -> RotaryTable:
    table = SerialRotaryTable(url, timeout_s=timeout_s, n_axes=n_axes)
    try:
        table.identify()
    except DriverError:
        table.close()
        raise
    return table


TABLE_OPENERS: dict[str, TableOpener] = {
    "serial": _open_serial_table,
    "socket": _open_serial_table,
    "loop": _open_serial_table,
    "": _open_serial_table,  # a bare device path
}


def url_scheme(url: str) -> str:
    """Scheme of ``url`` (``""`` for a bare path such as ``/dev/ttyUSB0``)."""
    return urllib.parse.urlsplit(url).scheme.lower()


def open_table(url: str, *, timeout_s: float = 1.0, n_axes: int = 3) -> RotaryTable:
    """A connected rotary table for ``url``; the link is checked with ``*IDN?``.

    :raises ValueError: unknown scheme.
    :raises LinkLost: the port cannot be opened.
    :raises DeviceTimeout: the device does not answer.
    :raises ProtocolError: it answers something that is not this protocol.
    """
    scheme = url_scheme(url)
    opener = TABLE_OPENERS.get(scheme)
    if opener is None:
        known = ", ".join(f"{s}://" for s in sorted(TABLE_OPENERS) if s)
        raise ValueError(f"unsupported table URL {url!r}: expected {known} or a device path")
    return opener(url, timeout_s, n_axes)
