"""SimBench: a whole simulated calibration bench on loopback, for the real drivers.

One :class:`SimClock` drives one :class:`TableController` (served over TCP in the real
text protocol by a :class:`TableServer`) and one :class:`DaqEngine` (served over Modbus
TCP by a :class:`DaqServer`) that samples one :class:`SensorPhysics` along the
controller's true motion. The real drivers connect to :attr:`SimBench.table_url`
(``socket://127.0.0.1:PORT``) and :attr:`SimBench.daq_url` (``modbus-tcp://127.0.0.1:PORT``)
exactly as they would to hardware.

The geometry the bench *believes* (table axes, mount rotation, lever arm) is in
:attr:`SimBench.geometry`; the physics uses the same axes and mount, while the sensor's
true lever arm and every other unmodelled effect live in the :class:`SensorTruth`, so a
run can conceal any effect of the catalogue from the bench.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from drivers.sim.clock import SimClock
from drivers.sim.daq_engine import DaqEngine
from drivers.sim.modbus_server import DaqServer
from drivers.sim.physics import SensorPhysics, SensorTruth, TemperatureModel
from drivers.sim.table_axis import AxisLimits
from drivers.sim.table_controller import TableController
from drivers.sim.table_server import TableServer

DEFAULT_AXES = ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
"""Outer vertical, middle horizontal, inner vertical (the recording format's default)."""

FULL_SCALE = {"V": 10.0, "count": 65535.0, "m/s2": 200.0, "g": 20.0}
"""DAQ input range per channel unit: ADAM ±10 V, a 16-bit count, ±20 g."""


@dataclass(frozen=True)
class BenchGeometry:
    """What the bench believes about its table and fixture (the recording sidecar's ``table``).

    :param axes: (k, 3) unit rotation axes, outermost first, at all angles zero.
    :param mount_rotation: (3, 3) sensor nominal frame -> innermost table frame.
    :param lever_arm_m: (3,) believed sensor position in the innermost table frame (m).
    """

    axes: npt.NDArray[np.float64]
    mount_rotation: npt.NDArray[np.float64]
    lever_arm_m: npt.NDArray[np.float64]


class SimBench:
    """Table server + DAQ server + physics on one simulated clock, on ephemeral loopback ports.

    :param truth: the unit under test (default: :meth:`SensorTruth.typical` for ``seed``).
    :param speed: simulated seconds per wall second.
    :param sample_rate_hz: DAQ sample rate (Hz).
    :param seed: seeds the unit, the noise and the controller.
    :param g_local_m_s2: local gravity (m/s²).
    :param axes: (k, 3) table axes, k <= 3 (the DAQ latches at most three encoders).
    :param mount: (3, 3) mount rotation (true and believed).
    :param lever_arm_m: (3,) lever arm the bench believes (the true one is the truth's
        ``lever_arm`` effect, zero without it).
    :param temperature: the sensor temperature course (default: the physics' model).
    :param ring_capacity: DAQ ring size (samples); default: as much as the controller's
        motion history allows, at most 65535.
    :param buffer_wall_s: wall seconds of data the simulated bench keeps for a host that
        falls behind (motion history and DAQ ring both scale with ``speed``), so that a busy
        host at a high simulation speed sees what it would see at speed 1: a DAQ buffer of
        about a minute of simulated time, or more.
    :param table_latency_s: wall seconds the table takes to answer a command.
    :param axis_limits: each axis's :class:`~drivers.sim.table_axis.AxisLimits` (or its keywords),
        outermost first: a bench file's table (``station.execution.devices``); ``None``: the
        defaults on every axis.
    """

    def __init__(
        self,
        truth: SensorTruth | None = None,
        *,
        speed: float = 1.0,
        sample_rate_hz: float = 100.0,
        seed: int = 0,
        g_local_m_s2: float = 9.81535,
        axes: Sequence[Sequence[float]] | npt.NDArray[np.float64] = DEFAULT_AXES,
        mount: npt.NDArray[np.float64] | None = None,
        lever_arm_m: Sequence[float] = (0.0, 0.0, 0.0),
        temperature: TemperatureModel | None = None,
        ring_capacity: int | None = None,
        table_latency_s: float = 0.0,
        buffer_wall_s: float = 10.0,
        axis_limits: Sequence[AxisLimits | Mapping[str, float]] | None = None,
    ) -> None:
        axes_arr = np.atleast_2d(np.asarray(axes, dtype=float))
        if axes_arr.ndim != 2 or axes_arr.shape[1] != 3 or not 1 <= axes_arr.shape[0] <= 3:
            raise ValueError(f"SimBench: axes must be (k, 3) with 1 <= k <= 3, got shape {axes_arr.shape}")
        arm = np.asarray(lever_arm_m, dtype=float).reshape(-1)
        if arm.shape != (3,) or not np.all(np.isfinite(arm)):
            raise ValueError(f"SimBench: lever_arm_m must be 3 finite values, got {lever_arm_m!r}")
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise ValueError(f"SimBench: sample_rate_hz must be finite and > 0, got {sample_rate_hz!r}")
        self.truth = SensorTruth.typical(seed=seed) if truth is None else truth
        self.sample_rate_hz = float(sample_rate_hz)
        self.g_local_m_s2 = float(g_local_m_s2)
        self.clock = SimClock(speed)
        self.physics = SensorPhysics(
            self.truth,
            axes_arr,
            mount,
            g_local_m_s2,
            seed=seed,
            temperature=temperature,
            sample_rate_hz=sample_rate_hz,
        )
        self.geometry = BenchGeometry(axes_arr, self.physics.mount.copy(), arm)
        history_s = max(60.0, buffer_wall_s * float(speed))
        self.controller = TableController(
            self.clock,
            n_axes=axes_arr.shape[0],
            limits=None
            if axis_limits is None
            else [a if isinstance(a, AxisLimits) else AxisLimits(**a) for a in axis_limits],
            seed=seed,
            history_s=history_s,
        )
        if ring_capacity is None:
            ring_capacity = max(1, min(0xFFFF, int(0.8 * history_s * sample_rate_hz)))
        self.engine = DaqEngine(
            self.clock,
            self.physics,
            self.controller.kinematics,
            sample_rate_hz=sample_rate_hz,
            ring_capacity=ring_capacity,
            channel_unit=self.truth.channel_unit,
            full_scale=FULL_SCALE[self.truth.channel_unit],
            n_axes=axes_arr.shape[0],
        )
        self.table_server = TableServer(self.controller, latency_s=table_latency_s)
        self.daq_server: DaqServer | None = None
        try:
            self.table_url = self.table_server.serve_tcp("127.0.0.1", 0)
            self.daq_server = DaqServer(self.engine)
            self.daq_url = self.daq_server.url
        except BaseException:
            self.close()
            raise

    @property
    def channel_unit(self) -> str:
        """Unit of the DAQ's acceleration channels."""
        return self.truth.channel_unit

    def close(self) -> None:
        """Stop both servers (idempotent); connected drivers see their links drop."""
        if self.daq_server is not None:
            self.daq_server.close()
        self.table_server.close()

    def __enter__(self) -> SimBench:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
