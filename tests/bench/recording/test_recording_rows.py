"""The block formatter of the recording writer: the csv module's bytes, and a bit-exact round trip."""

from __future__ import annotations

import csv
import io
import struct
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bench.recording import RecordingWriter, Sidecar, TableAxis, TableGeometry, read_recording
from bench.recording.rows import format_block, format_rows_with_extras


def csv_module_text(block: np.ndarray) -> str:
    """The reference: csv.writer over lists of floats, NaN written as an empty field."""
    rows = [["" if v != v else v for v in r] for r in block.tolist()]
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()


def bits(x: float) -> int:
    return struct.unpack("<q", struct.pack("<d", x))[0]


finite_or_nan = st.floats(allow_infinity=False, allow_subnormal=True, width=64)


@settings(max_examples=60, deadline=None)
# A recording row has at least t, ax, ay, az (csv quotes a row that is one empty field).
@given(arrays(np.float64, st.tuples(st.integers(0, 40), st.integers(4, 9)), elements=finite_or_nan))
def test_format_block_is_the_csv_module_text_and_parses_back_bit_exact(block: np.ndarray) -> None:
    text = format_block(block)
    assert text == csv_module_text(block)
    lines = text.splitlines()
    assert len(lines) == block.shape[0]
    for row, line in zip(block.tolist(), lines, strict=True):
        fields = line.split(",")
        assert len(fields) == block.shape[1]
        for v, f in zip(row, fields, strict=True):
            if v != v:
                assert f == ""
            else:
                assert bits(float(f)) == bits(v)  # also keeps the sign of -0.0


def test_extremes_and_negative_zero() -> None:
    block = np.array([[5e-324, -0.0, 1.7976931348623157e308, 0.1 + 0.2, np.nan, -2.5e-10]])
    assert format_block(block) == "5e-324,-0.0,1.7976931348623157e+308,0.30000000000000004,,-2.5e-10\n"


def test_extra_columns_are_quoted_by_the_csv_module() -> None:
    block = np.array([[1.0, np.nan], [2.5, 3.0]])
    text = format_rows_with_extras(block, ["note"], {"note": ["a,b", 'say "hi"']})
    assert text == '1.0,,"a,b"\n2.5,3.0,"say ""hi"""\n'


def test_writer_blocks_round_trip_bit_exact_with_missing_temperatures(tmp_path: Path) -> None:
    axes = (TableAxis("outer", (0.0, 0.0, 1.0)), TableAxis("inner", (1.0, 0.0, 0.0)))
    sc = Sidecar("SN-R", "V", 1000.0, 9.81, table=TableGeometry(axes))
    rng = np.random.default_rng(5)
    n = 3000
    t = 1234.5 + np.arange(n) / 1000.0
    accel = rng.normal(1.5, 0.3, (n, 3)) * 10.0 ** rng.integers(-8, 8, (n, 3))
    table = rng.uniform(-720.0, 720.0, (n, 2))
    temp = 25.0 + rng.normal(0.0, 0.01, n)
    temp[rng.random(n) < 0.1] = np.nan
    with RecordingWriter(tmp_path / "r.csv", sc, 2, True) as w:
        for i in range(0, n, 777):  # blocks that do not divide n
            w.append(t[i : i + 777], accel[i : i + 777], table[i : i + 777], temp[i : i + 777])
    rec = read_recording(tmp_path / "r.csv")
    np.testing.assert_array_equal(rec.t_s, t)
    np.testing.assert_array_equal(rec.accel_raw, accel)
    np.testing.assert_array_equal(rec.table_deg, table)
    assert rec.temp_c is not None
    np.testing.assert_array_equal(np.isnan(rec.temp_c), np.isnan(temp))
    np.testing.assert_array_equal(rec.temp_c[~np.isnan(temp)], temp[~np.isnan(temp)])
