"""Message pairs for every register of the DAQ map: registers <-> engineering values.

Expected words are worked out by hand from IEEE 754 and two's complement (or, for the
property tests, by pymodbus' own converter, an independent formulation).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient

from drivers import daq_blocks as blk
from drivers import daq_registers as reg

DT = ModbusTcpClient.DATATYPE


# -- instantaneous channels (HR 0-7) ------------------------------------------------------
@pytest.mark.parametrize(
    ("code", "raw", "value"),
    [
        (0x0143, 0, -10.0),
        (0x0143, 65535, 10.0),
        (0x0143, 32768, -10.0 + 32768 * 20.0 / 65535),
        (0x0142, 16384, -5.0 + 16384 * 10.0 / 65535),
        (0x0148, 65535, 10.0),
        (0x0103, 0, -0.150),
        (0x0180, 0, 4.0),
        (0x0180, 65535, 20.0),
        (0x0180, 16384, 4.0 + 16.0 * 16384 / 65535),
    ],
)
def test_raw_register_to_value(code: int, raw: int, value: float) -> None:
    assert reg.raw_to_value(raw, reg.input_range(code)) == pytest.approx(value, abs=1e-12)


def test_value_to_raw_rounds_and_pins_at_the_range_ends() -> None:
    rng = reg.input_range(0x0143)
    assert reg.value_to_raw(0.0, rng) == 32768  # 32767.5 rounds to even 32768
    assert reg.value_to_raw(10.0, rng) == 65535
    assert reg.value_to_raw(12.0, rng) == 65535
    assert reg.value_to_raw(-12.0, rng) == 0
    assert reg.value_to_raw(math.nan, rng) == 65535


@given(st.floats(-10.0, 10.0))
def test_value_raw_round_trip_within_half_a_step(value: float) -> None:
    rng = reg.input_range(0x0143)
    back = reg.raw_to_value(reg.value_to_raw(value, rng), rng)
    assert abs(back - value) <= 0.5 * 20.0 / 65535 + 1e-12


def test_engineering_type_code_uses_full_scale_and_unknown_codes_are_rejected() -> None:
    rng = reg.input_range(reg.TYPE_CODE_ENGINEERING, 58.8)
    assert (rng.lo, rng.hi) == (-58.8, 58.8)
    with pytest.raises(ValueError, match="0x9999"):
        reg.input_range(0x9999)
    with pytest.raises(ValueError, match="full scale"):
        reg.input_range(reg.TYPE_CODE_ENGINEERING)
    with pytest.raises(ValueError, match=r"0\.\.65535"):
        reg.raw_to_value(70000, reg.input_range(0x0143))


# -- status bits (HR 100-115) and per-sample status ------------------------------------------
def test_channel_status_bits_are_the_adam_6017_bits() -> None:
    assert reg.ChannelStatus.OVER_RANGE == 0x0002
    assert reg.ChannelStatus.UNDER_RANGE == 0x0004
    assert reg.ChannelStatus.OPEN_CIRCUIT == 0x0008
    assert reg.ChannelStatus.ADC_FAIL == 0x0080
    assert reg.ChannelStatus.CALIBRATION_ERROR == 0x0200
    # A 32-bit status value travels high word first.
    assert reg.u32_to_regs(int(reg.ChannelStatus.OPEN_CIRCUIT | reg.ChannelStatus.OVER_RANGE)) == [0, 0x000A]


def test_sample_status_bits_and_names() -> None:
    assert reg.sample_status_bit(0, "over") == 0x001
    assert reg.sample_status_bit(1, "under") == 0x010
    assert reg.sample_status_bit(2, "open") == 0x100
    assert reg.sample_status_names(0x100 | 0x001) == ("over_range:ax", "open_circuit:az")
    assert reg.sample_status_names(0) == ()
    with pytest.raises(ValueError, match="0, 1 or 2"):
        reg.sample_status_bit(3, "open")


# -- 32-bit values: word order ------------------------------------------------------------
@pytest.mark.parametrize(
    ("value", "words"),
    [
        (1.0, [0x3F80, 0x0000]),
        (-2.5, [0xC020, 0x0000]),
        (25.0, [0x41C8, 0x0000]),
        (math.pi, [0x4049, 0x0FDB]),
    ],
)
def test_float32_word_order_is_high_word_first(value: float, words: list[int]) -> None:
    assert reg.f32_to_regs(value) == words
    assert reg.regs_to_f32(words) == pytest.approx(value, rel=1e-7)


def test_uint32_word_order() -> None:
    assert reg.u32_to_regs(0x12345678) == [0x1234, 0x5678]
    assert reg.regs_to_u32([0x1234, 0x5678]) == 0x12345678
    with pytest.raises(ValueError):
        reg.u32_to_regs(1 << 32)


@given(st.floats(width=32, allow_nan=False))
def test_float32_agrees_with_pymodbus_converter(value: float) -> None:
    words = reg.f32_to_regs(value)
    assert words == ModbusTcpClient.convert_to_registers(value, DT.FLOAT32, word_order="big")
    assert reg.regs_to_f32(words) == ModbusTcpClient.convert_from_registers(
        words, DT.FLOAT32, word_order="big"
    )


@given(st.integers(0, (1 << 32) - 1))
def test_uint32_agrees_with_pymodbus_converter(value: int) -> None:
    assert reg.u32_to_regs(value) == ModbusTcpClient.convert_to_registers(value, DT.UINT32, word_order="big")


# -- sequence numbers ---------------------------------------------------------------------
def test_sequence_unwrap_across_the_32_bit_wrap() -> None:
    m = 1 << 32
    assert reg.unwrap_seq(2, m - 3) == m + 2
    assert reg.unwrap_seq(m - 1, m + 5) == m - 1
    assert reg.unwrap_seq(1234, 1000) == 1234
    assert reg.unwrap_seq((5 * m + 17) % m, 5 * m) == 5 * m + 17


# -- buffered records -----------------------------------------------------------------------
def test_record_message_pair() -> None:
    words = blk.encode_records(
        seq=np.array([0x12345]),
        accel=np.array([[1.0, -2.5, 0.0]]),
        temp_c=np.array([25.0]),
        encoder_deg=np.array([[90.0, 180.0, 190.0]]),  # 180 and 190 wrap to -180 and -170
        status=np.array([0x100]),
    )
    assert words.tolist() == [
        0x2345, 0x0100,
        0x3F80, 0x0000, 0xC020, 0x0000, 0x0000, 0x0000,
        0x41C8, 0x0000,
        0x055D, 0x4A80, 0xF545, 0x6B00, 0xF5DE, 0x0180,
    ]  # fmt: skip
    rec = blk.decode_records(words, n_axes=3)
    assert rec.seq16.tolist() == [0x2345]
    assert rec.status.tolist() == [0x100]
    assert rec.accel.tolist() == [[1.0, -2.5, 0.0]]
    assert rec.temp_c.tolist() == [25.0]
    np.testing.assert_allclose(rec.encoder_deg, [[90.0, -180.0, -170.0]], atol=1e-9)


def test_records_round_trip_with_fewer_axes_and_nan_temperature() -> None:
    rng = np.random.default_rng(1)
    n = 50
    accel = rng.normal(1.5, 0.5, (n, 3))
    enc = rng.uniform(-180, 180, (n, 2))
    words = blk.encode_records(
        np.arange(65530, 65530 + n), accel, np.full(n, np.nan), enc, np.zeros(n, dtype=np.uint16)
    )
    assert words.shape == (n * reg.RECORD_WORDS,)
    rec = blk.decode_records(words, n_axes=2)
    assert rec.seq16.tolist() == [(65530 + i) & 0xFFFF for i in range(n)]  # wraps at 16 bits
    np.testing.assert_allclose(rec.accel, accel, rtol=2**-24)
    np.testing.assert_allclose(rec.encoder_deg, enc, atol=0.5e-6 + 1e-9)
    assert np.all(np.isnan(rec.temp_c))
    assert rec.encoder_deg.shape == (n, 2)


def test_decode_rejects_partial_records_and_bad_words() -> None:
    with pytest.raises(ValueError, match="multiple of 16"):
        blk.decode_records([0] * 17, n_axes=3)
    with pytest.raises(ValueError, match=r"0\.\.65535"):
        blk.decode_records([70000] + [0] * 15, n_axes=3)
    with pytest.raises(ValueError, match="encoder axes"):
        blk.decode_records([0] * 16, n_axes=4)


# -- window header, stream status, read plan ------------------------------------------------
def test_window_header_message_pair() -> None:
    assert blk.encode_window_header((1 << 32) + 7, 120) == [0, 7, 120, 16]
    h = blk.decode_window_header([0x0001, 0x0002, 5, 16])
    assert (h.first_seq32, h.n_valid, h.record_words) == (0x10002, 5, 16)
    with pytest.raises(ValueError, match="record size 8"):
        blk.decode_window_header([0, 0, 5, 8])
    with pytest.raises(ValueError, match="capacity"):
        blk.decode_window_header([0, 0, 121, 16])


def test_stream_status_message_pair() -> None:
    s = blk.StreamStatus(
        counter32=70000,
        oldest32=61808,
        sample_rate_hz=1000.0,
        ring_capacity=8192,
        n_axes=3,
        running=True,
        channel_unit=reg.ChannelUnit.G,
        full_scale=6.0,
    )
    words = blk.encode_stream_status(s)
    assert words == [0x0001, 0x1170, 0x0000, 0xF170, 0x447A, 0x0000, 8192, 16, 120, 3, 1, 3, 0x40C0, 0x0000]
    assert blk.decode_stream_status(words) == s
    bad_unit = [*words[:11], 9, *words[12:]]
    with pytest.raises(ValueError, match="HR 411"):
        blk.decode_stream_status(bad_unit)
    zero_rate = [*words[:4], 0, 0, *words[6:]]
    with pytest.raises(ValueError, match="HR 404"):
        blk.decode_stream_status(zero_rate)


def test_channel_unit_codes() -> None:
    assert [reg.ChannelUnit.from_text(u) for u in ("V", "count", "m/s2", "g")] == [0, 1, 2, 3]
    with pytest.raises(ValueError, match="mV"):
        reg.ChannelUnit.from_text("mV")


def test_read_plan_respects_the_modbus_limit() -> None:
    assert blk.read_spans(504, 300) == [(504, 125), (629, 125), (754, 50)]
    assert blk.read_spans(504, 0) == []
    spans = blk.read_spans(reg.HR_RECORDS, reg.WINDOW_CAPACITY * reg.RECORD_WORDS)
    assert all(c <= reg.MAX_READ_REGS for _, c in spans)
    assert sum(c for _, c in spans) == reg.WINDOW_CAPACITY * reg.RECORD_WORDS
    assert reg.HR_END <= 0xFFFF
