"""The two small protocols the bench depends on: a rotary table and a DAQ.

The sequencer (``bench/``) is typed against these and never against a driver class,
as bluesky plans are typed against ``Movable``/``Readable``. A real driver
(``drivers/table.py``, ``drivers/modbus_daq.py``) and anything else that satisfies the
protocol can be plugged in.

Angles are degrees at this edge (the wire protocols speak degrees), rates deg/s.
Axis numbers are 1-based, 1 = outermost, as in the recording format.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt


class AxisMode(enum.Enum):
    """Control mode of one table axis."""

    POSITION = "POS"
    RATE = "RATE"
    OSCILLATION = "OSC"
    OFF = "OFF"


@dataclass(frozen=True)
class AxisStatus:
    """State of one table axis as the controller reports it.

    :param position_deg: encoder angle (deg), wrapped as the controller reports it.
    :param rate_deg_s: measured rate (deg/s).
    :param mode: control mode.
    :param in_position: the axis is within its position window and settled.
    :param fault: controller fault text for this axis, ``None`` when healthy.
    """

    position_deg: float
    rate_deg_s: float
    mode: AxisMode
    in_position: bool
    fault: str | None = None


@dataclass(frozen=True)
class TableStatus:
    """Whole-table status.

    :param axes: one :class:`AxisStatus` per axis, outermost first.
    :param interlock_ok: the interlock chain is closed (motion allowed).
    :param estop: the emergency stop is pressed.
    :param errors: entries drained from the controller's error queue.
    """

    axes: tuple[AxisStatus, ...]
    interlock_ok: bool
    estop: bool
    errors: tuple[str, ...] = ()


@runtime_checkable
class RotaryTable(Protocol):
    """A multi-axis rotary table (position, rate and oscillation modes per axis)."""

    @property
    def n_axes(self) -> int:
        """Number of axes, outermost first."""
        ...

    def move_to(self, angles_deg: tuple[float, ...], timeout_s: float) -> None:
        """Command every axis to a position and block until all are in position.

        :raises DeviceTimeout: not in position before ``timeout_s``.
        :raises LimitError: an angle outside the axis limits.
        :raises InterlockOpen: the interlock is open.
        """
        ...

    def start_rate(self, axis: int, rate_deg_s: float) -> None:
        """Put one axis in rate mode at a constant rate (returns once accepted)."""
        ...

    def start_oscillation(self, axis: int, amplitude_deg: float, period_s: float) -> None:
        """Put one axis in sinusoidal oscillation about its current centre."""
        ...

    def positions_deg(self) -> tuple[float, ...]:
        """Encoder angles of all axes (deg)."""
        ...

    def rates_deg_s(self) -> tuple[float, ...]:
        """Measured rates of all axes (deg/s)."""
        ...

    def stop(self) -> None:
        """Decelerate every axis to rest and hold position (the safe state)."""
        ...

    def status(self) -> TableStatus:
        """Modes, in-position flags, interlock, E-stop and queued errors."""
        ...

    def close(self) -> None:
        """Release the transport."""
        ...


@dataclass(frozen=True)
class SampleBlock:
    """A block of consecutive DAQ samples.

    :param first_seq: sequence number of the first sample (the DAQ's sample counter).
    :param t_s: (n,) DAQ time stamps (s since the DAQ's stream start).
    :param accel: (n, 3) raw accelerometer outputs in the DAQ's channel unit.
    :param temp_c: (n,) sensor temperature (°C), NaN where not measured.
    :param table_deg: (n, n_axes) encoder angles latched with each sample (deg), or
        ``None`` when the DAQ does not latch the table.
    :param flags: status flags of this block (e.g. ``"open_circuit:ax"``).
    """

    first_seq: int
    t_s: npt.NDArray[np.float64]
    accel: npt.NDArray[np.float64]
    temp_c: npt.NDArray[np.float64]
    table_deg: npt.NDArray[np.float64] | None = None
    flags: tuple[str, ...] = field(default_factory=tuple)

    @property
    def n(self) -> int:
        """Number of samples in the block."""
        return int(self.t_s.shape[0])


@runtime_checkable
class Daq(Protocol):
    """A sampling DAQ with a buffered block mode and a sample counter."""

    @property
    def sample_rate_hz(self) -> float:
        """Configured sample rate (Hz)."""
        ...

    @property
    def channel_unit(self) -> str:
        """Unit of the acceleration channels: ``V``, ``count``, ``m/s2`` or ``g``."""
        ...

    def start(self) -> None:
        """Start buffered acquisition; the sample counter restarts at 0."""
        ...

    def read_block(self, max_samples: int, timeout_s: float) -> SampleBlock:
        """Read the samples buffered since the last call (at most ``max_samples``).

        :raises DataGap: the sample counter jumped (samples were lost); never hidden.
        :raises DeviceTimeout: no answer before ``timeout_s``.
        """
        ...

    def stop(self) -> None:
        """Stop buffered acquisition."""
        ...

    def status(self) -> dict[str, object]:
        """Decoded status word (flags by name), temperature, buffer fill."""
        ...

    def close(self) -> None:
        """Release the connection."""
        ...
