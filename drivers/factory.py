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

This is the one place where production code reaches the simulator (``drivers.sim``): only when a
URL (the bench file's, or the settings') is ``sim://``, and only then is it imported. A process
that drives a real bench never loads it. Callers name a simulated unit with
:func:`simulated_unit` and hand it on as a :data:`SimulatedTruth`; they never build one.
"""

from __future__ import annotations

import urllib.parse
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeAlias

from drivers.base import Daq, RotaryTable
from drivers.errors import DriverError
from drivers.modbus_daq import ModbusDaq
from drivers.table import SerialRotaryTable

if TYPE_CHECKING:
    from drivers.sim.bench import SimBench
    from drivers.sim.physics import SensorTruth
    from drivers.sim.process import SimBenchProcess

TableOpener = Callable[[str, float, int], RotaryTable]

SimulatedTruth: TypeAlias = "SensorTruth"
"""The simulated unit a ``sim://`` bench carries (:class:`drivers.sim.physics.SensorTruth`), as
the station passes it on to :func:`open_bench` without looking inside."""


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


# ---- DAQ and whole benches -------------------------------------------------------------------
# DAQ URLs: ``modbus-tcp://host:port`` (default port 502), the calbench register map
# (docs/daq-registers.md). ``sim://?speed=100&rate=1000&seed=1&unit=V`` in open_bench starts
# a SimBench on loopback and connects the real drivers to it.

SIM_PARAMS = {"speed": float, "rate": float, "seed": int, "unit": str}


def open_daq(url: str, *, timeout_s: float = 1.0, device_id: int = 1, retries: int = 1) -> Daq:
    """A connected DAQ for ``url`` (``modbus-tcp://host:port``); the module id is checked.

    :raises ValueError: unknown scheme (``sim://`` needs the table too: :func:`open_bench`).
    :raises LinkLost: nothing accepts connections there.
    :raises ProtocolError: the device is not this DAQ.
    """
    scheme = url_scheme(url)
    if scheme == "modbus-tcp":
        return ModbusDaq(url, device_id=device_id, timeout_s=timeout_s, retries=retries)
    if scheme == "sim":
        raise ValueError(f"DAQ URL {url!r}: a simulated DAQ follows a simulated table; use open_bench")
    raise ValueError(f"unsupported DAQ URL {url!r}: expected modbus-tcp://host:port")


def parse_sim_url(url: str) -> dict[str, float | int | str]:
    """``sim://?speed=100&rate=1000&seed=1&unit=V`` -> keyword arguments (speed, rate, seed, unit).

    :raises ValueError: another scheme, an unknown or repeated parameter, or a bad value.
    """
    parts = urllib.parse.urlsplit(url)
    if parts.scheme.lower() != "sim":
        raise ValueError(f"not a sim:// URL: {url!r}")
    out: dict[str, float | int | str] = {}
    query = urllib.parse.parse_qs(parts.query, keep_blank_values=True)
    for key, values in query.items():
        if key not in SIM_PARAMS:
            raise ValueError(f"sim URL {url!r}: unknown parameter {key!r}; expected {', '.join(SIM_PARAMS)}")
        if len(values) != 1:
            raise ValueError(f"sim URL {url!r}: parameter {key!r} given {len(values)} times")
        try:
            out[key] = SIM_PARAMS[key](values[0])
        except ValueError:
            kind = SIM_PARAMS[key].__name__
            raise ValueError(f"sim URL {url!r}: {key}={values[0]!r} is not a {kind}") from None
    return out


@dataclass
class BenchDevices:
    """A table and a DAQ opened together, and the simulated bench behind them if any.

    The caller owns it: :meth:`close` (or ``with``) closes the drivers, then the simulation.
    """

    table: RotaryTable
    daq: Daq
    sim: SimBench | SimBenchProcess | None = None

    def close(self) -> None:
        """Close the drivers, then stop the simulated bench (idempotent)."""
        try:
            self.table.close()
            self.daq.close()
        finally:
            if self.sim is not None:
                self.sim.close()

    def __enter__(self) -> BenchDevices:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_bench(
    table_url: str,
    daq_url: str | None = None,
    *,
    timeout_s: float = 1.0,
    n_axes: int = 3,
    truth: SimulatedTruth | None = None,
    sim_geometry: dict[str, Any] | None = None,
    sim_process: bool = False,
) -> BenchDevices:
    """Open the table and the DAQ; ``table_url`` ``sim://...`` starts a :class:`SimBench` first.

    With ``sim://`` the DAQ URL must be absent or ``sim://`` too (one simulation feeds
    both); ``truth`` chooses the simulated unit, ``sim_geometry`` the simulated bench's
    ``axes``, ``mount``, ``lever_arm_m`` and ``g_local_m_s2`` (:class:`SimBench` keywords;
    default: its own, with ``n_axes`` of :data:`drivers.sim.bench.DEFAULT_AXES`); ``sim_process`` runs the
    simulation in its own process (:class:`SimBenchProcess`: it keeps time like hardware however
    busy this process is), otherwise in threads of this one (tests that inject faults reach it there).

    :raises ValueError: a bad URL or combination.
    """
    if url_scheme(table_url) == "sim":
        from drivers.sim.bench import DEFAULT_AXES, SimBench
        from drivers.sim.physics import SensorTruth
        from drivers.sim.process import SimBenchProcess

        if daq_url is not None and url_scheme(daq_url) != "sim":
            raise ValueError(f"table {table_url!r} is simulated, DAQ {daq_url!r} is not: use sim:// for both")
        p = parse_sim_url(table_url)
        seed = int(p.get("seed", 0))
        if truth is None:
            truth = SensorTruth.typical(str(p.get("unit", "V")), seed)
        speed, rate = float(p.get("speed", 1.0)), float(p.get("rate", 100.0))
        geometry = sim_geometry or {"axes": DEFAULT_AXES[:n_axes]}
        sim: SimBench | SimBenchProcess
        if sim_process:
            sim = SimBenchProcess(truth, speed=speed, sample_rate_hz=rate, seed=seed, **geometry)
        else:
            sim = SimBench(truth, speed=speed, sample_rate_hz=rate, seed=seed, **geometry)
        try:
            table = open_table(sim.table_url, timeout_s=timeout_s, n_axes=n_axes)
            try:
                daq = open_daq(sim.daq_url, timeout_s=timeout_s)
            except BaseException:
                table.close()
                raise
        except BaseException:
            sim.close()
            raise
        return BenchDevices(table, daq, sim)
    if daq_url is None:
        raise ValueError(f"table {table_url!r} is real: a DAQ URL (modbus-tcp://host:port) is needed")
    table = open_table(table_url, timeout_s=timeout_s, n_axes=n_axes)
    try:
        return BenchDevices(table, open_daq(daq_url, timeout_s=timeout_s))
    except BaseException:
        table.close()
        raise


def unit_seed(serial: str) -> int:
    """Seed of a simulated unit: CRC-32 of its serial (stable across processes)."""
    return zlib.crc32(serial.encode("utf-8"))


def simulated_unit(serial: str, age_days: float) -> SimulatedTruth:
    """The simulated sensor with this serial, ``age_days`` after its first registration: the
    typical ``V`` unit drawn with :func:`unit_seed`, aged (negative ages count as 0)."""
    from drivers.sim.physics import SensorTruth

    seed = unit_seed(serial)
    return SensorTruth.typical("V", seed).aged(max(0.0, age_days), seed)
