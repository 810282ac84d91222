"""The simulated DAQ's sampling engine: physics sampled on the simulated clock into a ring.

Sample k of a stream started at simulated time t0 is taken at ``t0 + k / sample_rate_hz``
and carries sequence number k. :meth:`DaqEngine.update` produces every sample whose time
has come (``<= clock.now_s()``) by calling
``physics.sample(t_s, kinematics, temp_c) -> SensorSamples(raw (n,3), encoder_deg (n,k),
temp_c (n,))`` in chunks, so the DAQ follows the simulated table exactly. The ring keeps the
last ``ring_capacity`` samples; older ones are gone, as on a real DAQ whose host read
too slowly, and the reader sees that from the oldest sequence number.

Faults: :meth:`drop_next` skips the next n sequence numbers (lost blocks: the counter
advances, the ring never holds them); :meth:`set_open_circuit` pins a channel at +full
scale with its open-circuit bit set (ADAM burnout: raw 65535).

Thread-safe: one lock guards the whole state; the Modbus server calls in from its loop
thread while a test or the bench injects faults from another.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from drivers import daq_blocks as blk
from drivers import daq_registers as reg

FloatArray = npt.NDArray[np.float64]


class Clock(Protocol):
    """What the engine needs of a simulated clock."""

    def now_s(self) -> float:
        """Simulated seconds."""
        ...


class Physics(Protocol):
    """What the engine needs of the sensor physics (``drivers/sim/physics.py``)."""

    def sample(self, t_s: FloatArray, kinematics: Callable[[FloatArray], Any], temp_c: Any) -> Any:
        """Raw outputs (n, 3), encoder angles (n, k) and temperature (n,) at times ``t_s``."""
        ...


@dataclass(frozen=True)
class Window:
    """Consecutive samples from the ring, starting at or after a requested sequence.

    :param first_seq: sequence number of sample 0 (the requested one unless it is gone).
    :param registers: (n·16,) records in the layout of :data:`daq_registers.RECORD_DTYPE`.
    :param n: number of samples.
    """

    first_seq: int
    registers: npt.NDArray[np.uint16]
    n: int


@dataclass(frozen=True)
class Latest:
    """The most recent sample, for the instantaneous registers."""

    accel: FloatArray
    temp_c: float
    status: int


class DaqEngine:
    """Samples ``physics`` on the grid ``t0 + k / sample_rate_hz`` into a ring buffer.

    :param clock: the simulated clock shared with the table.
    :param physics: the sensor model.
    :param kinematics: the table's ``kinematics(t_s (n,)) -> TableKinematics``.
    :param sample_rate_hz: sample rate (Hz), > 0.
    :param ring_capacity: samples kept (1..65535).
    :param channel_unit: unit of the physics' raw outputs (``V``, ``count``, ``m/s2``, ``g``).
    :param full_scale: ±input range in ``channel_unit``; beyond it a value is clipped
        and flagged over/under range.
    :param n_axes: encoder axes latched per sample (0..3).
    :param temp_c: temperature passed to the physics (``None``: the physics' own model).
    :param chunk: most samples per physics call.
    """

    def __init__(
        self,
        clock: Clock,
        physics: Physics,
        kinematics: Callable[[FloatArray], Any],
        *,
        sample_rate_hz: float,
        ring_capacity: int = 8192,
        channel_unit: str = "V",
        full_scale: float = 10.0,
        n_axes: int = 3,
        temp_c: float | None = None,
        chunk: int = 2048,
    ) -> None:
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise ValueError(f"sample_rate_hz must be finite and > 0, got {sample_rate_hz!r}")
        if not 1 <= ring_capacity <= 0xFFFF:
            raise ValueError(f"ring_capacity must be 1..65535 samples, got {ring_capacity}")
        if not (math.isfinite(full_scale) and full_scale > 0):
            raise ValueError(f"full_scale must be finite and > 0, got {full_scale!r}")
        if not 0 <= n_axes <= reg.MAX_ENCODER_AXES:
            raise ValueError(f"n_axes must be 0..{reg.MAX_ENCODER_AXES}, got {n_axes}")
        self.unit = reg.ChannelUnit.from_text(channel_unit)
        self._clock = clock
        self._physics = physics
        self._kinematics = kinematics
        self.sample_rate_hz = float(sample_rate_hz)
        self.capacity = ring_capacity
        self.full_scale = float(full_scale)
        self.n_axes = n_axes
        self._temp_c = temp_c
        self._chunk = chunk
        self._lock = threading.RLock()
        self._seq = np.zeros(ring_capacity, dtype=np.int64)
        self._accel = np.zeros((ring_capacity, 3))
        self._temp = np.full(ring_capacity, np.nan)
        self._enc = np.zeros((ring_capacity, n_axes))
        self._status = np.zeros(ring_capacity, dtype=np.uint16)
        self._open = [False, False, False]
        self._running = False
        self._t0_s = 0.0
        self._next_k = 0
        self._stored = 0
        self._drop_pending = 0
        self._latest = Latest(np.zeros(3), math.nan, 0)

    # -- control -------------------------------------------------------------------
    def start(self) -> None:
        """Start a stream at the clock's now: the counter restarts at 0, the ring empties."""
        with self._lock:
            self._t0_s = self._clock.now_s()
            self._next_k = 0
            self._stored = 0
            self._drop_pending = 0
            self._running = True

    def stop(self) -> None:
        """Stop producing samples (after producing those already due); the ring stays readable."""
        with self._lock:
            self.update()
            self._running = False

    @property
    def running(self) -> bool:
        """Acquisition is running."""
        return self._running

    def drop_next(self, n: int) -> None:
        """Fault: the next ``n`` samples are never stored (the counter still advances)."""
        if n < 0:
            raise ValueError(f"drop count must be >= 0, got {n}")
        with self._lock:
            self._drop_pending += n

    def set_open_circuit(self, channel: int, on: bool) -> None:
        """Fault: acceleration channel 0-2 open (burnout) from the next sample on."""
        if channel not in reg.ACCEL_CHANNELS:
            raise ValueError(f"acceleration channel must be 0, 1 or 2, got {channel}")
        with self._lock:
            self._open[channel] = on

    # -- state ---------------------------------------------------------------------
    @property
    def counter(self) -> int:
        """Sequence number of the next sample (samples produced, dropped ones included)."""
        with self._lock:
            return self._next_k

    @property
    def oldest_seq(self) -> int:
        """Oldest sequence number in the ring (the counter when the ring is empty)."""
        with self._lock:
            if self._stored == 0:
                return self._next_k
            return int(self._ordered_seq()[0])

    def latest(self) -> Latest:
        """The most recent sample (zeros before the first)."""
        with self._lock:
            return self._latest

    # -- production ----------------------------------------------------------------
    def update(self) -> None:
        """Produce every sample due by ``clock.now_s()``."""
        with self._lock:
            if not self._running:
                return
            due = math.floor((self._clock.now_s() - self._t0_s) * self.sample_rate_hz + 1e-9) + 1
            if due - self._next_k > self.capacity + self._drop_pending:
                # Only the newest `capacity` samples could survive in the ring.
                skipped = due - self.capacity - self._next_k
                self._drop_pending = max(0, self._drop_pending - skipped)
                self._next_k = due - self.capacity
            while self._next_k < due:
                if self._drop_pending:
                    n_drop = min(self._drop_pending, due - self._next_k)
                    self._next_k += n_drop
                    self._drop_pending -= n_drop
                    continue
                n = min(self._chunk, due - self._next_k)
                self._produce(np.arange(self._next_k, self._next_k + n, dtype=np.int64))
                self._next_k += n

    def _produce(self, k: npt.NDArray[np.int64]) -> None:
        t_s = self._t0_s + k / self.sample_rate_hz
        temp_arg = None if self._temp_c is None else np.full(k.shape[0], self._temp_c)
        out = self._physics.sample(t_s, self._kinematics, temp_arg)
        accel = np.array(out.raw, dtype=np.float64).reshape(k.shape[0], 3)
        enc = np.asarray(out.encoder_deg, dtype=np.float64).reshape(k.shape[0], -1)
        temp = np.asarray(out.temp_c, dtype=np.float64).reshape(k.shape[0])
        if enc.shape[1] < self.n_axes:
            raise ValueError(f"physics gave {enc.shape[1]} encoder axes, the DAQ latches {self.n_axes}")
        status = np.zeros(k.shape[0], dtype=np.uint16)
        for c in reg.ACCEL_CHANNELS:
            if self._open[c]:
                accel[:, c] = self.full_scale
                status |= np.uint16(reg.sample_status_bit(c, "open"))
                continue
            over = ~(accel[:, c] <= self.full_scale)  # NaN reads as over range
            under = accel[:, c] < -self.full_scale
            accel[over, c] = self.full_scale
            accel[under, c] = -self.full_scale
            status[over] |= np.uint16(reg.sample_status_bit(c, "over"))
            status[under] |= np.uint16(reg.sample_status_bit(c, "under"))
        pos = (self._stored + np.arange(k.shape[0])) % self.capacity
        self._seq[pos] = k
        self._accel[pos] = accel
        self._temp[pos] = temp
        self._enc[pos] = enc[:, : self.n_axes]
        self._status[pos] = status
        self._stored += k.shape[0]
        self._latest = Latest(accel[-1].copy(), float(temp[-1]), int(status[-1]))

    # -- reading -------------------------------------------------------------------
    def _ordered_seq(self) -> npt.NDArray[np.int64]:
        if self._stored <= self.capacity:
            return self._seq[: self._stored]
        pos = self._stored % self.capacity
        return np.concatenate((self._seq[pos:], self._seq[:pos]))

    def window(self, from_seq: int, max_n: int = reg.WINDOW_CAPACITY) -> Window:
        """Up to ``max_n`` consecutive samples starting at the first one ``>= from_seq``.

        ``first_seq > from_seq`` means the samples in between are gone (overwritten or
        dropped); with nothing at or after ``from_seq`` yet, the window is empty and
        ``first_seq == from_seq``.
        """
        with self._lock:
            self.update()
            ordered = self._ordered_seq()
            i0 = int(np.searchsorted(ordered, from_seq, side="left"))
            if i0 == ordered.shape[0]:
                return Window(from_seq, np.zeros(0, dtype=np.uint16), 0)
            run = ordered[i0 : i0 + max_n]
            breaks = np.nonzero(np.diff(run) != 1)[0]
            n = int(breaks[0]) + 1 if breaks.size else run.shape[0]
            base = self._stored - ordered.shape[0]
            pos = (base + i0 + np.arange(n)) % self.capacity
            regs = blk.encode_records(
                self._seq[pos], self._accel[pos], self._temp[pos], self._enc[pos], self._status[pos]
            )
            return Window(int(run[0]), regs, n)
