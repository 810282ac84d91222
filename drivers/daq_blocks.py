"""Buffered block mode of the DAQ map: record layout, window header, stream status (pure codecs).

The addresses and scalar codecs are in :mod:`drivers.daq_registers`; ``docs/daq-registers.md``
documents the whole map. All words big-endian, 32-bit values high word first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from drivers import daq_registers as reg

RECORD_DTYPE = np.dtype(
    [
        ("seq16", ">u2"),
        ("status", ">u2"),
        ("accel", ">f4", (3,)),
        ("temp", ">f4"),
        ("enc", ">i4", (reg.MAX_ENCODER_AXES,)),
    ]
)
"""One buffered sample: 16 registers (32 bytes, big-endian).

=====  ======  =========================================================
word   type    content
=====  ======  =========================================================
0      uint16  low 16 bits of the sample's sequence number (a check)
1      uint16  per-sample :class:`SampleStatus` bits
2-7    FLOAT32 ax, ay, az in the channel unit (HR 411)
8-9    FLOAT32 sensor temperature (°C), NaN when not measured
10-15  INT32   encoder angle of table axes 1..3 latched at the sample
               instant, in 1e-6 deg; unused axes 0
=====  ======  =========================================================
"""
assert RECORD_DTYPE.itemsize == 2 * reg.RECORD_WORDS


def encode_records(
    seq: npt.NDArray[np.int64],
    accel: npt.NDArray[np.float64],
    temp_c: npt.NDArray[np.float64],
    encoder_deg: npt.NDArray[np.float64],
    status: npt.NDArray[np.integer],
) -> npt.NDArray[np.uint16]:
    """Pack n samples into n·16 registers (:data:`RECORD_DTYPE`).

    :param seq: (n,) sequence numbers.
    :param accel: (n, 3) acceleration values in the channel unit (rounded to binary32).
    :param temp_c: (n,) temperature (°C), NaN when not measured.
    :param encoder_deg: (n, k) encoder angles, k <= 3; wrapped to [-180, 180) and
        rounded to 1e-6 deg.
    :param status: (n,) :class:`SampleStatus` words.
    :returns: (n·16,) register values.
    """
    n = seq.shape[0]
    k = encoder_deg.shape[1] if encoder_deg.ndim == 2 else 0
    if k > reg.MAX_ENCODER_AXES:
        raise ValueError(f"at most {reg.MAX_ENCODER_AXES} encoder axes fit a record, got {k}")
    rec = np.zeros(n, dtype=RECORD_DTYPE)
    rec["seq16"] = np.asarray(seq, dtype=np.int64) & 0xFFFF
    rec["status"] = status
    rec["accel"] = accel
    rec["temp"] = temp_c
    if k:
        counts = np.round(reg.wrap_deg(encoder_deg) / reg.ENCODER_SCALE_DEG)
        rec["enc"][:, :k] = np.clip(counts, -180_000_000, 179_999_999).astype(np.int32)
    return rec.view(">u2").astype(np.uint16)


@dataclass(frozen=True)
class DecodedRecords:
    """Buffered samples decoded from registers.

    :param seq16: (n,) low 16 bits of each sequence number.
    :param status: (n,) :class:`SampleStatus` words.
    :param accel: (n, 3) channel values.
    :param temp_c: (n,) temperature (°C).
    :param encoder_deg: (n, k) encoder angles (deg).
    """

    seq16: npt.NDArray[np.int64]
    status: npt.NDArray[np.int64]
    accel: npt.NDArray[np.float64]
    temp_c: npt.NDArray[np.float64]
    encoder_deg: npt.NDArray[np.float64]


def decode_records(regs: list[int] | npt.NDArray[np.integer], n_axes: int) -> DecodedRecords:
    """Unpack registers of whole records (inverse of :func:`encode_records`).

    :param regs: (n·16,) register values.
    :param n_axes: number of latched encoder axes (HR 409), 0..3.
    :raises ValueError: the length is not a whole number of records.
    """
    words = np.asarray(regs, dtype=np.int64)
    if words.ndim != 1 or words.shape[0] % reg.RECORD_WORDS:
        raise ValueError(f"records need a multiple of {reg.RECORD_WORDS} registers, got {words.shape}")
    if not 0 <= n_axes <= reg.MAX_ENCODER_AXES:
        raise ValueError(f"encoder axes must be 0..{reg.MAX_ENCODER_AXES}, got {n_axes}")
    if words.size and (words.min() < 0 or words.max() > 0xFFFF):
        raise ValueError("register values must be 0..65535")
    rec = words.astype(">u2").view(RECORD_DTYPE)
    return DecodedRecords(
        seq16=rec["seq16"].astype(np.int64),
        status=rec["status"].astype(np.int64),
        accel=rec["accel"].astype(np.float64),
        temp_c=rec["temp"].astype(np.float64),
        encoder_deg=rec["enc"][:, :n_axes].astype(np.float64) * reg.ENCODER_SCALE_DEG,
    )


@dataclass(frozen=True)
class WindowHeader:
    """HR 500-503: what the window holds after a write to HR 420.

    :param first_seq32: low 32 bits of the sequence number of record 0.
    :param n_valid: number of consecutive samples in the window.
    :param record_words: registers per record (:data:`reg.RECORD_WORDS`).
    """

    first_seq32: int
    n_valid: int
    record_words: int


def encode_window_header(first_seq: int, n_valid: int) -> list[int]:
    """HR 500-503 for a window starting at ``first_seq`` holding ``n_valid`` samples."""
    if not 0 <= n_valid <= reg.WINDOW_CAPACITY:
        raise ValueError(f"window holds 0..{reg.WINDOW_CAPACITY} samples, got {n_valid}")
    return [*reg.u32_to_regs(first_seq % reg.SEQ_MODULUS), n_valid, reg.RECORD_WORDS]


def decode_window_header(regs: list[int]) -> WindowHeader:
    """Inverse of :func:`encode_window_header`; rejects a foreign record layout."""
    if len(regs) != reg.WINDOW_HEADER_REGS:
        raise ValueError(f"window header is {reg.WINDOW_HEADER_REGS} registers, got {len(regs)}")
    header = WindowHeader(reg.regs_to_u32(regs[0:2]), regs[2], regs[3])
    if header.record_words != reg.RECORD_WORDS:
        raise ValueError(f"record size {header.record_words} words, expected {reg.RECORD_WORDS}")
    if header.n_valid > reg.WINDOW_CAPACITY:
        raise ValueError(f"window claims {header.n_valid} samples, capacity is {reg.WINDOW_CAPACITY}")
    return header


def read_spans(start: int, count: int, max_regs: int = reg.MAX_READ_REGS) -> list[tuple[int, int]]:
    """Split ``count`` registers from ``start`` into (address, count) reads of <= ``max_regs``."""
    if count < 0 or not 1 <= max_regs <= reg.MAX_READ_REGS:
        raise ValueError(f"bad read plan: count {count}, max_regs {max_regs}")
    return [(a, min(max_regs, start + count - a)) for a in range(start, start + count, max_regs)]


@dataclass(frozen=True)
class StreamStatus:
    """HR 400-413, the stream status block.

    :param counter32: low 32 bits of the next sequence number the DAQ will produce
        (samples produced since start, dropped ones included).
    :param oldest32: low 32 bits of the oldest sequence number still in the ring.
    :param sample_rate_hz: sample rate (Hz).
    :param ring_capacity: ring size (samples).
    :param n_axes: encoder axes latched per sample.
    :param running: acquisition is running (HR 410).
    :param channel_unit: unit of the buffered acceleration values.
    :param full_scale: ±range of the acceleration channels in ``channel_unit``.
    """

    counter32: int
    oldest32: int
    sample_rate_hz: float
    ring_capacity: int
    n_axes: int
    running: bool
    channel_unit: reg.ChannelUnit
    full_scale: float


def encode_stream_status(s: StreamStatus) -> list[int]:
    """:class:`StreamStatus` -> HR 400-413."""
    return [
        *reg.u32_to_regs(s.counter32 % reg.SEQ_MODULUS),
        *reg.u32_to_regs(s.oldest32 % reg.SEQ_MODULUS),
        *reg.f32_to_regs(s.sample_rate_hz),
        s.ring_capacity,
        reg.RECORD_WORDS,
        reg.WINDOW_CAPACITY,
        s.n_axes,
        int(s.running),
        int(s.channel_unit),
        *reg.f32_to_regs(s.full_scale),
    ]


def decode_stream_status(regs: list[int]) -> StreamStatus:
    """HR 400-413 -> :class:`StreamStatus`.

    :raises ValueError: wrong length, a foreign record layout, a unit code or axis
        count outside the map, or a non-positive rate.
    """
    if len(regs) != reg.STREAM_STATUS_REGS:
        raise ValueError(f"stream status is {reg.STREAM_STATUS_REGS} registers, got {len(regs)}")
    if regs[reg.HR_RECORD_WORDS - reg.HR_SAMPLE_COUNTER] != reg.RECORD_WORDS:
        raise ValueError(f"HR {reg.HR_RECORD_WORDS}: record size {regs[7]}, expected {reg.RECORD_WORDS}")
    if regs[reg.HR_WINDOW_CAPACITY - reg.HR_SAMPLE_COUNTER] != reg.WINDOW_CAPACITY:
        raise ValueError(f"HR {reg.HR_WINDOW_CAPACITY}: window {regs[8]}, expected {reg.WINDOW_CAPACITY}")
    n_axes = regs[reg.HR_N_ENCODER_AXES - reg.HR_SAMPLE_COUNTER]
    if n_axes > reg.MAX_ENCODER_AXES:
        raise ValueError(f"HR {reg.HR_N_ENCODER_AXES}: {n_axes} encoder axes, at most {reg.MAX_ENCODER_AXES}")
    rate = reg.regs_to_f32(regs[4:6])
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"HR {reg.HR_SAMPLE_RATE}: sample rate {rate} Hz is not positive")
    try:
        unit = reg.ChannelUnit(regs[reg.HR_CHANNEL_UNIT - reg.HR_SAMPLE_COUNTER])
    except ValueError:
        raise ValueError(f"HR {reg.HR_CHANNEL_UNIT}: unknown channel unit code {regs[11]}") from None
    return StreamStatus(
        counter32=reg.regs_to_u32(regs[0:2]),
        oldest32=reg.regs_to_u32(regs[2:4]),
        sample_rate_hz=rate,
        ring_capacity=regs[6],
        n_axes=n_axes,
        running=bool(regs[reg.HR_ACQ_CONTROL - reg.HR_SAMPLE_COUNTER]),
        channel_unit=unit,
        full_scale=reg.regs_to_f32(regs[12:14]),
    )
