"""The reader's fast path parses the CSV in pieces: pieces join without losing, doubling or
shifting a row, and a bad value in a late piece is still named by its own row."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bench.recording import RecordingError, numeric_table, read_recording

SIDECAR = {
    "format": "calbench-recording/1",
    "unit": {"serial": "SN-CHUNK"},
    "channel_unit": "V",
    "sample_rate_hz": 100.0,
    "g_local_m_s2": 9.81,
    "table": {"axes": [{"name": "outer", "axis": [0, 0, 1]}]},
}
N_ROWS = 257


def values() -> np.ndarray:
    """(N_ROWS, 6) t, ax, ay, az, table_1, temp: full-precision doubles of varied text length."""
    rng = np.random.default_rng(5)
    out = np.empty((N_ROWS, 6))
    out[:, 0] = np.arange(N_ROWS) * 0.01
    out[:, 1:4] = 1.5 + rng.normal(0.0, 0.3, (N_ROWS, 3))
    out[:, 4] = rng.uniform(-180.0, 180.0, N_ROWS)
    out[:, 5] = 25.0 + rng.normal(0.0, 1.0, N_ROWS)
    return out


def write(tmp_path: Path, lines: list[str], newline: str = "\n") -> Path:
    csv = tmp_path / "run.csv"
    csv.write_bytes((newline.join(["t,ax,ay,az,table_1,temp", *lines]) + newline).encode())
    (tmp_path / "run.json").write_text(json.dumps(SIDECAR))
    return csv


def lines_of(v: np.ndarray) -> list[str]:
    return [",".join(repr(float(x)) for x in row) for row in v]


@pytest.mark.parametrize("chunk_bytes", [1, 37, 100, 4096, 1 << 22])
@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_pieces_join_to_every_row_bit_exact(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, chunk_bytes: int, newline: str
) -> None:
    monkeypatch.setattr(numeric_table, "CHUNK_BYTES", chunk_bytes)
    v = values()
    rec = read_recording(write(tmp_path, lines_of(v), newline))
    assert rec.n_samples == N_ROWS
    np.testing.assert_array_equal(rec.t_s, v[:, 0])
    np.testing.assert_array_equal(rec.accel_raw, v[:, 1:4])
    assert rec.table_deg is not None and rec.temp_c is not None
    np.testing.assert_array_equal(rec.table_deg[:, 0], v[:, 4])
    np.testing.assert_array_equal(rec.temp_c, v[:, 5])
    assert rec.t_s.flags.c_contiguous and rec.temp_c.flags.c_contiguous


def test_last_row_without_newline_is_kept(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(numeric_table, "CHUNK_BYTES", 64)
    v = values()
    csv = write(tmp_path, lines_of(v))
    csv.write_bytes(csv.read_bytes().rstrip(b"\n"))
    rec = read_recording(csv)
    assert rec.n_samples == N_ROWS
    np.testing.assert_array_equal(rec.accel_raw[-1], v[-1, 1:4])


@pytest.mark.parametrize("row", [1, 130, N_ROWS])
def test_bad_value_in_any_piece_names_its_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, row: int
) -> None:
    monkeypatch.setattr(numeric_table, "CHUNK_BYTES", 100)
    lines = lines_of(values())
    fields = lines[row - 1].split(",")
    fields[2] = "1_5"
    lines[row - 1] = ",".join(fields)
    with pytest.raises(RecordingError) as info:
        read_recording(write(tmp_path, lines))
    assert (info.value.row, info.value.line) == (row, row + 1)
    assert "column 'ay'" in str(info.value)


def test_blank_line_at_a_piece_boundary_is_an_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    lines = lines_of(values())
    first_100 = len(("\n".join(lines[:100]) + "\n").encode())
    monkeypatch.setattr(numeric_table, "CHUNK_BYTES", first_100)  # the next piece begins with the blank line
    with pytest.raises(RecordingError) as info:
        read_recording(write(tmp_path, [*lines[:100], "", *lines[100:]]))
    assert info.value.line == 102
    assert "blank line inside the data" in str(info.value)


def test_wrong_field_count_in_a_late_piece(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(numeric_table, "CHUNK_BYTES", 100)
    lines = lines_of(values())
    lines[200] += ",7"
    with pytest.raises(RecordingError) as info:
        read_recording(write(tmp_path, lines))
    assert info.value.row == 201
    assert "7 fields, expected 6" in str(info.value)
