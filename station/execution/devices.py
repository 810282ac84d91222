"""The bench's devices as its bench file describes them: the file, the opened table and DAQ
(real, or a simulated bench built to the file's geometry), the check that they are that bench,
and the recording's sidecar from both.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from bench.bench_config import SIM_BENCH_FILE, BenchConfig, apply_to_daq, load_bench_config
from bench.procedures import DEFAULT_TABLE_LIMITS, TableLimits
from bench.recording.model import Sidecar
from bench.sequencer.faults import resumable_fault
from drivers.daq_registers import LINK_MAX_SAMPLES_S
from drivers.factory import BenchDevices, SimulatedTruth, open_bench, open_daq, open_table
from station.settings import Settings

T = TypeVar("T")


class DeviceNotAnswering(ConnectionError):
    """A device of the bench file did not open with a fault that passes
    (:func:`bench.sequencer.faults.resumable_fault`: no reply, a link refused or dropped, a
    garbled reply); the message names the device, its URL and the driver's error.

    :ivar device: ``"table"`` or ``"DAQ"``. :ivar url: the device's URL (the bench file's).
    :ivar cause: the driver's error.
    """

    def __init__(self, device: str, url: str, cause: BaseException) -> None:
        super().__init__(f"the {device} at {url} did not answer: {type(cause).__name__}: {cause}")
        self.device = device
        self.url = url
        self.cause = cause


def _opened(device: str, url: str, opener: Callable[[], T]) -> T:
    """``opener()``; a fault that passes raised as :class:`DeviceNotAnswering` naming ``device``."""
    try:
        return opener()
    except Exception as exc:
        if resumable_fault(exc):
            raise DeviceNotAnswering(device, url, exc) from exc
        raise


def sim_url(settings: Settings, speed: float | None, seed: int, unit: str = "V") -> str:
    """The ``sim://`` URL of a simulated bench with this speed, seed and channel unit."""
    speed = speed or settings.sim_speed
    return f"sim://?speed={speed:g}&rate={settings.sim_sample_rate_hz:g}&seed={seed}&unit={unit}"


def check_sim_link(speed: float, sample_rate_hz: float) -> None:
    """A simulated bench at ``speed`` with its DAQ at ``sample_rate_hz`` asks ``speed ·
    sample_rate_hz`` samples per wall second of the DAQ's Modbus link, which carries at most
    :data:`~drivers.daq_registers.LINK_MAX_SAMPLES_S`; beyond it every run loses samples
    until it ends in error, so it is refused.

    :raises ValueError: the demand exceeds the link (the limit and the largest speed named).
    """
    demand = speed * sample_rate_hz
    if demand > LINK_MAX_SAMPLES_S:
        raise ValueError(
            f"simulation speed {speed:g} with the simulated DAQ at {sample_rate_hz:g} Hz asks "
            f"{demand:,.0f} samples/s of the DAQ's Modbus link, which carries at most "
            f"{LINK_MAX_SAMPLES_S:,.0f}: use a speed of at most {LINK_MAX_SAMPLES_S / sample_rate_hz:g} "
            "(or a lower CALBENCH_SIM_SAMPLE_RATE_HZ)"
        )


def bench_config_for(settings: Settings, sim: bool) -> BenchConfig:
    """The bench file of the settings (``CALBENCH_BENCH_FILE``); without one, the simulated
    bench's (``--sim`` or a ``sim://`` table URL).

    :raises BenchConfigError: the file is unreadable or invalid (file and key named).
    :raises ValueError: a real bench without a bench file.
    """
    if settings.bench_file is not None:
        return load_bench_config(settings.bench_file)
    if sim or settings.table_url.lower().startswith("sim:"):
        return load_bench_config(SIM_BENCH_FILE)
    raise ValueError(
        f"table {settings.table_url!r} is a real bench: its geometry, local g and DAQ channels come from a "
        "bench file (CALBENCH_BENCH_FILE or --bench-file; format in docs/bench-config.md)"
    )


def table_limits(settings: Settings, sim: bool | None = None) -> TableLimits:
    """The limits of the table that runs — the one place every check of a procedure takes them
    from (start, queue, preview, resume, the sequencer's move deadlines, the agent, the planner):
    the bench file's ``[table.limits]`` (:func:`bench_config_for`), else
    :data:`~bench.procedures.DEFAULT_TABLE_LIMITS`; the default too for a real table without a
    bench file, which no run starts on (:func:`bench_config_for` refuses it there).

    :param sim: a simulated bench (``--sim``); default ``settings.sim``.
    :raises BenchConfigError: the bench file is unreadable or invalid (file and key named).
    """
    sim = settings.sim if sim is None else sim
    if settings.bench_file is None and not sim and not settings.table_url.lower().startswith("sim:"):
        return DEFAULT_TABLE_LIMITS
    return bench_config_for(settings, sim).table_limits()


def _sim_geometry(config: BenchConfig) -> dict[str, Any]:
    geometry: dict[str, Any] = {
        "axes": [list(a.axis) for a in config.axes],
        "mount": np.array(config.mount_rotation, dtype=float),
        "lever_arm_m": config.lever_arm_m,
        "g_local_m_s2": config.gravity.g_local_m_s2,
    }
    if config.limits is not None:
        geometry["axis_limits"] = sim_axis_limits(config.limits)
    return geometry


def sim_axis_limits(limits: TableLimits) -> list[dict[str, float]]:
    """The simulated controller's limits of a bench file's table (``AxisLimits`` keywords per
    axis): its rates and accelerations; a continuous axis unlimited (±180°), another its travel
    within the controller's ±180°. The controller's own in-position time stays its default."""
    out = []
    for i in range(limits.n_axes):
        lo, hi = (-180.0, 180.0) if limits.continuous[i] else (limits.pos_lo_deg[i], limits.pos_hi_deg[i])
        out.append(
            {
                "rate_deg_s": limits.max_rate_deg_s[i],
                "acc_deg_s2": limits.max_acc_deg_s2[i],
                "pos_lo_deg": max(lo, -180.0),
                "pos_hi_deg": min(hi, 180.0),
            }
        )
    return out


def open_devices(
    settings: Settings,
    sim: bool,
    sim_speed: float | None,
    seed: int,
    truth: SimulatedTruth | None = None,
    config: BenchConfig | None = None,
) -> BenchDevices:
    """Table and DAQ of the bench file ``config`` (default :func:`bench_config_for`): a
    simulated bench built to its geometry (``sim``, a ``sim://`` file, unit ``truth`` or the
    seed's typical one; in its own process when ``settings.sim_process``) or the file's URLs;
    the DAQ is checked against the file and its channels mapped to the sensor's x, y, z.
    """
    config = config or bench_config_for(settings, sim)
    n_axes = len(config.axes)
    if sim or config.simulated:
        check_sim_link(sim_speed or settings.sim_speed, settings.sim_sample_rate_hz)
        url = sim_url(settings, sim_speed, seed, config.channel_unit)
        if not sim and settings.bench_file is None and settings.table_url.lower().startswith("sim:"):
            url = settings.table_url  # a sim:// table URL with its own parameters
        devices = open_bench(
            url,
            truth=truth,
            n_axes=n_axes,
            sim_geometry=_sim_geometry(config),
            sim_process=settings.sim_process,
        )
    else:
        devices = _open_real(config, n_axes)
    try:
        devices.daq = apply_to_daq(config, devices.daq)
    except BaseException:
        devices.close()
        raise
    return devices


def _open_real(config: BenchConfig, n_axes: int) -> BenchDevices:
    """The table and DAQ at the bench file's URLs.

    :raises DeviceNotAnswering: one of them does not answer (the other is closed).
    """
    table_url, daq_url = config.table_url, config.daq_url
    if daq_url is None:
        raise ValueError(
            f"{config.path}: the table {table_url!r} is real: a DAQ URL (modbus-tcp://host:port) is needed"
        )
    table = _opened("table", table_url, lambda: open_table(table_url, n_axes=n_axes))
    try:
        return BenchDevices(table, _opened("DAQ", daq_url, lambda: open_daq(daq_url)))
    except BaseException:
        table.close()
        raise


def check_devices(devices: BenchDevices, config: BenchConfig) -> None:
    """The opened devices are the bench the file describes (axes; a simulation's geometry).

    :raises ValueError: they differ (the file named).
    """
    if devices.table.n_axes != len(config.axes):
        raise ValueError(
            f"{config.path}: table.axes lists {len(config.axes)} axes, the table has {devices.table.n_axes}"
        )
    if devices.sim is not None:
        geo = devices.sim.geometry
        same = (
            np.allclose(geo.axes, [a.axis for a in config.axes], atol=1e-9)
            and np.allclose(geo.mount_rotation, config.mount_rotation, atol=1e-9)
            and np.allclose(geo.lever_arm_m, config.lever_arm_m, atol=1e-12)
            and abs(devices.sim.g_local_m_s2 - config.gravity.g_local_m_s2) < 1e-9
        )
        if not same:
            raise ValueError(
                f"{config.path}: the simulated bench's axes, mount, lever arm or g differ from the bench file"
            )


def bench_sidecar(
    devices: BenchDevices,
    unit_serial: str,
    procedure: str,
    config: BenchConfig,
    g_local_m_s2: float | None = None,
) -> Sidecar:
    """The sidecar: units and rate from the DAQ, table geometry and local g from the bench file
    (``g_local_m_s2`` overrides the file's g).

    :raises ValueError: the devices are not the bench the file describes.
    """
    check_devices(devices, config)
    return Sidecar(
        unit_serial=unit_serial,
        channel_unit=devices.daq.channel_unit,
        sample_rate_hz=devices.daq.sample_rate_hz,
        g_local_m_s2=config.gravity.g_local_m_s2 if g_local_m_s2 is None else g_local_m_s2,
        procedure=procedure,
        table=config.table_geometry(),
    )
