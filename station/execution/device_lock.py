"""One driver per device: the lock on each device path of a bench file.

The bench lock (:mod:`station.execution.bench_lock`) is one per bench *name* and data directory;
two bench agents configured under different names (or data directories) with bench files that
name the same serial port or the same TCP device would both drive it — two processes writing
commands to one table. So whoever takes a bench lock also takes a lock on each real device its
bench file names, machine-wide: an ``fcntl.flock`` on a file per device in
``CALBENCH_DEVICE_LOCK_DIR`` (default ``<temp dir>/calbench-device-locks``, shared by every data
directory of the machine), holding the holder as one JSON line. The device's key is what
reaches the same device whatever the spelling: a serial port's real path (symlinks such as
``/dev/serial/by-id/…`` resolved), a TCP device's ``host:port`` (the table's ``socket://``, the
DAQ's ``modbus-tcp://``). A second process asking for a held device is refused with
:class:`DeviceHeld`, one line naming the device, the holder (process kind, pid, host, bench,
since when) and the lock file. A simulated bench has no device to lock. Devices reached from
several hosts are not covered (each host has its own lock directory).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import fcntl
import hashlib
import json
import os
import re
import socket
import tempfile
import urllib.parse
from pathlib import Path
from typing import IO

from bench.bench_config import BenchConfig

DEFAULT_DIR_NAME = "calbench-device-locks"


class DeviceHeld(RuntimeError):
    """A device of the bench file is driven by another process; the message is one line naming
    the device, the holder and the lock file."""


@dataclasses.dataclass(frozen=True)
class Device:
    """One real device of a bench file.

    :param role: ``table`` or ``DAQ``. :param url: as the bench file gives it.
    :param key: what identifies the device whatever the spelling (a real path, ``host:port``).
    """

    role: str
    url: str
    key: str


def device_key(url: str) -> str:
    """The device ``url`` reaches: ``serial:///dev/x`` or a bare path -> its real path,
    ``socket://h:p`` / ``modbus-tcp://h:p`` -> ``tcp h:p`` (host lower-case, default port 502
    for Modbus)."""
    parsed = urllib.parse.urlsplit(url)
    scheme = parsed.scheme.lower()
    if scheme in ("", "serial"):
        path = parsed.path if scheme else url
        return os.path.realpath(path)
    host = (parsed.hostname or "").lower()
    port = parsed.port or (502 if scheme == "modbus-tcp" else 0)
    return f"tcp {host}:{port}"


def bench_devices(config: BenchConfig) -> list[Device]:
    """The real devices of ``config`` (none for the simulated bench)."""
    if config.simulated:
        return []
    out = [Device("table", config.table_url, device_key(config.table_url))]
    if config.daq_url is not None:
        out.append(Device("DAQ", config.daq_url, device_key(config.daq_url)))
    return out


def try_flock(path: Path) -> IO[str] | None:
    """``path`` (created with its folder if absent) opened and locked exclusively without
    waiting (``fcntl.flock``, dropped by the kernel when the process ends), or ``None`` when
    another open file description holds it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle = path.open("a+")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.close()
        return None
    return handle


def lock_dir(configured: Path | None) -> Path:
    """The machine-wide directory of the device locks (``configured``, else the temp dir's)."""
    if configured is not None:
        return configured
    return Path(tempfile.gettempdir()) / DEFAULT_DIR_NAME


def lock_file(directory: Path, key: str) -> Path:
    """The lock file of device ``key``: readable name plus a hash of the exact key."""
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", key)[-60:]
    digest = hashlib.sha256(key.encode()).hexdigest()[:12]
    return directory / f"device-{safe}-{digest}.lock"


class DeviceLocks:
    """Hold every real device of a bench file for this process.

    :param devices: the devices (:func:`bench_devices`).
    :param directory: the lock directory (:func:`lock_dir`).
    :param kind: what this process is (``calbench agent``, ``calbench run``…).
    :param bench: the bench name it drives them as.
    """

    def __init__(self, devices: list[Device], directory: Path, kind: str, bench: str) -> None:
        self.devices, self.directory, self.kind, self.bench = devices, directory, kind, bench
        self._handles: list[IO[str]] = []

    def acquire(self) -> DeviceLocks:
        """Lock every device, or none.

        :raises DeviceHeld: a device is held by another process (named).
        """
        try:
            for device in self.devices:
                self._handles.append(self._lock(device))
        except BaseException:
            self.release()
            raise
        return self

    def _lock(self, device: Device) -> IO[str]:
        path = lock_file(self.directory, device.key)
        handle = try_flock(path)
        if handle is None:
            raise DeviceHeld(
                f"the {device.role} {device.url} ({device.key}) is driven by {describe_holder(path)} "
                f"(lock {path})"
            ) from None
        record = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "kind": self.kind,
            "bench": self.bench,
            "device": device.key,
            "since": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        }
        handle.seek(0)
        handle.truncate()
        handle.write(json.dumps(record) + "\n")
        handle.flush()
        return handle

    def release(self) -> None:
        """Unlock every device held (idempotent)."""
        while self._handles:
            self._handles.pop().close()


def describe_holder(path: Path) -> str:
    """``calbench agent pid 123 on host lab-1 for bench 'b2' since 2026-11-27T06:20:00+00:00``
    from a held lock file (``another process`` when it cannot be read)."""
    try:
        raw = json.loads(path.read_text().splitlines()[0])
        return (
            f"{raw['kind']} pid {int(raw['pid'])} on host {raw['host']} for bench {raw['bench']!r} "
            f"since {raw['since']}"
        )
    except (OSError, ValueError, KeyError, IndexError, TypeError):
        return "another process"
