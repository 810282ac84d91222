"""Register map of the calbench Modbus TCP DAQ (ADAM-6017-like), and its codecs.

Pure: no I/O. Every address is a 0-based holding-register address (vendor manuals
write 40001 for address 0). Every 32-bit value occupies two registers, high word first
("big" word order, as pymodbus ``convert_from_registers(..., word_order="big")``), and
every register is big-endian on the wire, so a 32-bit value is big-endian as a whole.
The full map with its rationale is in ``docs/daq-registers.md``; the codecs of the
buffered records, window header and stream status are in :mod:`drivers.daq_blocks`.

Two views of the same acquisition:

* **Instantaneous channels** (ADAM-6017 compatible): HR 0-7 raw uint16 spread linearly
  over the channel's type-code range, ``value = lo + raw / 65535 · (hi − lo)``; HR 100-115
  status (32 bits per channel, :class:`ChannelStatus`); HR 200-207 type codes; HR 210
  module id; HR 300-301 temperature FLOAT32 (°C).
* **Buffered block mode**: a 32-bit sample counter, a ring of recent samples, and a
  *window*: write the wanted start sequence to HR 420-421, then read the window header
  (HR 500-503) and up to :data:`WINDOW_CAPACITY` records of :data:`RECORD_WORDS` registers
  (HR 504...), in reads of at most :data:`MAX_READ_REGS`. The header's ``first_seq`` is the
  first sample the ring still holds at or after the requested one, so a jump means
  samples were lost and the reader must say so.

Sample time is the DAQ's own sample clock: sample ``seq`` was taken at
``t = seq / sample_rate_hz`` after the stream start.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

MODULE_ID = 0x6017
MAX_READ_REGS = 125
"""Modbus application limit for one read (FC03: 125 registers)."""

LINK_MAX_SAMPLES_S = 20_000.0
"""What one reader of this map over Modbus TCP carries at most (samples/s): one FC03 read of
:data:`MAX_READ_REGS` registers takes ~0.4 ms on loopback (≈2600 round trips/s), measured in
docs/daq-registers.md ("Measured throughput"); a stream faster than this overflows the ring."""

N_CHANNELS = 8
ACCEL_CHANNELS = (0, 1, 2)
CHANNEL_NAMES = ("ax", "ay", "az")

# Instantaneous area (ADAM-6017 layout).
HR_AI_RAW = 0
HR_AI_STATUS = 100
HR_TYPE_CODE = 200
HR_MODULE_ID = 210
HR_TEMPERATURE = 300

# Stream status and control.
HR_SAMPLE_COUNTER = 400
HR_OLDEST_SEQ = 402
HR_SAMPLE_RATE = 404
HR_RING_CAPACITY = 406
HR_RECORD_WORDS = 407
HR_WINDOW_CAPACITY = 408
HR_N_ENCODER_AXES = 409
HR_ACQ_CONTROL = 410
HR_CHANNEL_UNIT = 411
HR_FULL_SCALE = 412
STREAM_STATUS_REGS = 14
"""HR 400-413 are read together as the stream status block."""

HR_READ_FROM_SEQ = 420

# Window.
HR_WINDOW = 500
WINDOW_HEADER_REGS = 4
HR_RECORDS = HR_WINDOW + WINDOW_HEADER_REGS
RECORD_WORDS = 16
WINDOW_CAPACITY = 120
HR_END = HR_RECORDS + RECORD_WORDS * WINDOW_CAPACITY
"""One past the last register of the map."""

MAX_ENCODER_AXES = 3
ENCODER_SCALE_DEG = 1e-6
"""Encoder angles travel as int32 counts of 1e-6 deg, wrapped to [-180, 180) deg."""

SEQ_MODULUS = 1 << 32


class ChannelStatus(enum.IntFlag):
    """Per-channel status bits of HR 100-115 (ADAM-6017 AI status)."""

    UART_TIMEOUT = 1 << 0
    OVER_RANGE = 1 << 1
    UNDER_RANGE = 1 << 2
    OPEN_CIRCUIT = 1 << 3
    ADC_FAIL = 1 << 7
    CALIBRATION_ERROR = 1 << 9


class SampleStatus(enum.IntFlag):
    """Per-sample status word of a buffered record: 3 bits per acceleration channel.

    Channel c (0 = ax) uses bits 3c (over range), 3c+1 (under range), 3c+2 (open circuit).
    """

    AX_OVER = 1 << 0
    AX_UNDER = 1 << 1
    AX_OPEN = 1 << 2
    AY_OVER = 1 << 3
    AY_UNDER = 1 << 4
    AY_OPEN = 1 << 5
    AZ_OVER = 1 << 6
    AZ_UNDER = 1 << 7
    AZ_OPEN = 1 << 8


def sample_status_bit(channel: int, kind: str) -> int:
    """Bit of :class:`SampleStatus` for ``channel`` (0-2) and ``kind`` (over, under, open)."""
    offset = {"over": 0, "under": 1, "open": 2}[kind]
    if channel not in ACCEL_CHANNELS:
        raise ValueError(f"acceleration channel must be 0, 1 or 2, got {channel}")
    return 1 << (3 * channel + offset)


def sample_status_names(status: int) -> tuple[str, ...]:
    """Flag names of a per-sample status word, e.g. ``("open_circuit:az",)``."""
    kinds = (("over", "over_range"), ("under", "under_range"), ("open", "open_circuit"))
    names = []
    for c, ch in enumerate(CHANNEL_NAMES):
        for kind, name in kinds:
            if status & sample_status_bit(c, kind):
                names.append(f"{name}:{ch}")
    return tuple(names)


class ChannelUnit(enum.IntEnum):
    """Code of HR 411: the unit of the buffered acceleration values."""

    V = 0
    COUNT = 1
    M_S2 = 2
    G = 3

    @property
    def text(self) -> str:
        """The unit as the recording format spells it."""
        return {0: "V", 1: "count", 2: "m/s2", 3: "g"}[int(self)]

    @classmethod
    def from_text(cls, unit: str) -> ChannelUnit:
        """Code for a unit string (``V``, ``count``, ``m/s2``, ``g``)."""
        for member in cls:
            if member.text == unit:
                return member
        raise ValueError(f"channel unit must be one of V, count, m/s2, g; got {unit!r}")


@dataclass(frozen=True)
class InputRange:
    """An ADAM type code's input range: ``value = lo + raw/65535·(hi − lo)``."""

    code: int
    lo: float
    hi: float
    unit: str


TYPE_CODES: dict[int, InputRange] = {
    r.code: r
    for r in (
        InputRange(0x0103, -0.150, 0.150, "V"),
        InputRange(0x0104, -0.500, 0.500, "V"),
        InputRange(0x0140, -1.0, 1.0, "V"),
        InputRange(0x0142, -5.0, 5.0, "V"),
        InputRange(0x0143, -10.0, 10.0, "V"),
        InputRange(0x0145, 0.0, 1.0, "V"),
        InputRange(0x0147, 0.0, 5.0, "V"),
        InputRange(0x0148, 0.0, 10.0, "V"),
        InputRange(0x0180, 4.0, 20.0, "mA"),
        InputRange(0x0181, -20.0, 20.0, "mA"),
        InputRange(0x0182, 0.0, 20.0, "mA"),
    )
}
TYPE_CODE_ENGINEERING = 0xFFFF
"""Type code of a channel carrying engineering units (``m/s2``, ``g``, ``count``):
its range is ±full scale (HR 412)."""


def input_range(type_code: int, full_scale: float | None = None) -> InputRange:
    """Range of a type code; :data:`TYPE_CODE_ENGINEERING` needs ``full_scale``."""
    if type_code == TYPE_CODE_ENGINEERING:
        if full_scale is None or not math.isfinite(full_scale) or full_scale <= 0:
            raise ValueError(f"engineering type code needs a positive full scale, got {full_scale!r}")
        return InputRange(type_code, -full_scale, full_scale, "")
    try:
        return TYPE_CODES[type_code]
    except KeyError:
        raise ValueError(f"unknown ADAM type code 0x{type_code:04X}") from None


def raw_to_value(raw: int, rng: InputRange) -> float:
    """Instantaneous uint16 register -> engineering value: ``lo + raw/65535·(hi − lo)``."""
    if not 0 <= raw <= 0xFFFF:
        raise ValueError(f"raw register value must be 0..65535, got {raw}")
    return rng.lo + raw / 65535.0 * (rng.hi - rng.lo)


def value_to_raw(value: float, rng: InputRange) -> int:
    """Engineering value -> uint16, rounded, pinned to 0 / 65535 outside the range."""
    if not math.isfinite(value):
        return 0xFFFF
    raw = round((value - rng.lo) / (rng.hi - rng.lo) * 65535.0)
    return min(max(raw, 0), 0xFFFF)


def u32_to_regs(value: int) -> list[int]:
    """Unsigned 32-bit -> [high word, low word]."""
    if not 0 <= value < SEQ_MODULUS:
        raise ValueError(f"uint32 out of range: {value}")
    return [value >> 16, value & 0xFFFF]


def regs_to_u32(regs: list[int] | tuple[int, ...]) -> int:
    """[high word, low word] -> unsigned 32-bit."""
    hi, lo = regs
    return (hi << 16) | lo


def f32_to_regs(value: float) -> list[int]:
    """FLOAT32 (IEEE 754 binary32) -> [high word, low word]."""
    words = np.array([value], dtype=">f4").view(">u2")
    return [int(words[0]), int(words[1])]


def regs_to_f32(regs: list[int] | tuple[int, ...]) -> float:
    """[high word, low word] -> float (binary32 widened to float64)."""
    return float(np.array(regs, dtype=">u2").view(">f4")[0])


def unwrap_seq(seq32: int, near: int) -> int:
    """Full sequence number whose low 32 bits are ``seq32``, nearest to ``near``.

    The registers carry ``seq mod 2**32`` (49.7 days at 1 kHz); the reader keeps the full
    count and resolves each reading against the number it expected.
    """
    diff = (seq32 - near) % SEQ_MODULUS
    if diff >= SEQ_MODULUS // 2:
        diff -= SEQ_MODULUS
    return near + diff


def wrap_deg(angle_deg: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Wrap angles to [-180, 180) deg."""
    return np.asarray((angle_deg + 180.0) % 360.0 - 180.0, dtype=np.float64)
