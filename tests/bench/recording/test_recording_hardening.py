"""Inputs a careless user or an attacker gives the recording reader: each one a clean RecordingError.

Every case here was once a traceback or a silently wrong number (issue 13): Python's
``float()`` read ``1_0`` as 10 and ``١٢`` as 12, a 400-digit sidecar integer overflowed, a
sidecar nested 100 000 deep blew the stack, a 200 000-character field broke the csv module.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bench.inputs import InputError, check_text, loads_json, parse_decimal
from bench.recording import RecordingError, read_recording
from tests.bench.recording.test_recording_errors import HEADER, ROWS, SIDECAR, expect, write


@pytest.mark.parametrize("text", ["1_0", "١٢", "１", "0x10", "1e", "--1", "1.5.2", "\u00a01", "one"])
def test_non_ascii_decimal_is_not_a_number(text: str) -> None:
    with pytest.raises(InputError, match="not a number"):
        parse_decimal(text)


@pytest.mark.parametrize(("text", "value"), [("1.5", 1.5), ("-.5", -0.5), ("5.", 5.0), (" +2e-3 ", 2e-3)])
def test_ascii_decimal_reads_as_python_does(text: str, value: float) -> None:
    assert parse_decimal(text) == value


@pytest.mark.parametrize("text", ["nan", "inf", "-Infinity", "1e999"])
def test_non_finite_is_refused(text: str) -> None:
    with pytest.raises(InputError, match="finite"):
        parse_decimal(text)


@pytest.mark.parametrize("field", ["1_0", "١٢", "１"])
def test_csv_field_python_would_read_is_refused_with_its_place(tmp_path: Path, field: str) -> None:
    rows = [*ROWS[:2], f"0.02,{field},1.5,1.7,0,0", ROWS[3]]
    err = expect(write(tmp_path, rows), "not a number")
    assert (err.row, err.line, err.column) == (3, 4, "ax")


def test_huge_field_is_refused_not_a_csv_traceback(tmp_path: Path) -> None:
    rows = [*ROWS[:2], "0.02," + "1" * 200_000 + ",1.5,1.7,0,0", ROWS[3]]
    err = expect(write(tmp_path, rows), "characters")
    assert err.line == 4


def test_nul_in_csv_is_refused_or_named(tmp_path: Path) -> None:
    rows = [*ROWS[:2], "0.02,1.5\x00,1.5,1.7,0,0", ROWS[3]]
    err = expect(write(tmp_path, rows))
    assert err.line == 4


def _sidecar_text(tmp_path: Path, text: str) -> Path:
    csv = write(tmp_path)
    (tmp_path / "run.json").write_text(text)
    return csv


def test_deeply_nested_sidecar_is_refused_before_parsing(tmp_path: Path) -> None:
    text = json.dumps(SIDECAR)[:-1] + ', "x": ' + "[" * 100_000 + "]" * 100_000 + "}"
    expect(_sidecar_text(tmp_path, text), "nested deeper than 32", "line 1")


def test_huge_sidecar_integer_is_refused(tmp_path: Path) -> None:
    text = json.dumps(SIDECAR).replace('"sample_rate_hz": 100.0', '"sample_rate_hz": ' + "9" * 400)
    expect(_sidecar_text(tmp_path, text), "integer of 400 digits")


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "1e999"])
def test_non_finite_sidecar_number_is_refused(tmp_path: Path, literal: str) -> None:
    text = json.dumps(SIDECAR).replace('"sample_rate_hz": 100.0', f'"sample_rate_hz": {literal}')
    expect(_sidecar_text(tmp_path, text), "finite")


def test_duplicate_sidecar_key_is_refused(tmp_path: Path) -> None:
    text = json.dumps(SIDECAR)[:-1] + ', "channel_unit": "g"}'
    expect(_sidecar_text(tmp_path, text), "duplicate key 'channel_unit'")


@pytest.mark.parametrize("serial", ["", "   ", " SN-7", "SN\x007", "SN-\u202e7"])
def test_empty_or_unprintable_serial_is_refused(tmp_path: Path, serial: str) -> None:
    expect(write(tmp_path, unit__serial=serial), "unit.serial")


def test_bidi_control_in_a_label_is_refused(tmp_path: Path) -> None:
    segs = [{"start_s": 0.0, "end_s": 0.01, "label": "pos\u202e10"}]
    expect(write(tmp_path, segments=segs), "segments[0].label", "U+202E")


@pytest.mark.parametrize("rate", [1e-300, 1e300, 10.0, 1000.0])
def test_sample_rate_must_agree_with_the_time_column(tmp_path: Path, rate: float) -> None:
    expect(write(tmp_path, sample_rate_hz=rate), "sample_rate_hz", "median step 0.01 s")


def test_sample_rate_within_tolerance_reads(tmp_path: Path) -> None:
    rec = read_recording(write(tmp_path, sample_rate_hz=110.0))
    assert rec.sidecar.sample_rate_hz == 110.0


@pytest.mark.parametrize("angle", ["1e10", "-1e10", "1000000.5", "-1000000.5"])
def test_table_angle_offset_by_1e10_deg_is_refused(tmp_path: Path, angle: str) -> None:
    rows = [*ROWS[:2], f"0.02,1.5,1.5,1.7,0,{angle}", ROWS[3]]
    err = expect(write(tmp_path, rows), "beyond ±1e+06 deg")
    assert (err.row, err.column) == (3, "table_2")


def test_table_angle_of_exactly_1e6_deg_reads(tmp_path: Path) -> None:
    rows = [*ROWS[:2], "0.02,1.5,1.5,1.7,-1000000,1000000", ROWS[3]]
    assert read_recording(write(tmp_path, rows)).n_samples == 4


def test_wrapped_and_multi_turn_angles_still_read(tmp_path: Path) -> None:
    rows = [r.replace(",0,0", ",-179.99,3600") for r in ROWS]
    rec = read_recording(write(tmp_path, rows))
    assert rec.table_deg is not None
    np.testing.assert_array_equal(rec.table_deg[:, 1], 3600.0)


def test_too_many_table_axes_is_refused(tmp_path: Path) -> None:
    axes = [{"name": f"a{i}", "axis": [0, 0, 1]} for i in range(7)]
    header = HEADER + "," + ",".join(f"table_{i}" for i in range(3, 8))
    rows = [r + ",0,0,0,0,0" for r in ROWS]
    expect(write(tmp_path, rows, header=header, table__axes=axes), "7 table axes")


def test_header_with_control_character_is_refused(tmp_path: Path) -> None:
    expect(write(tmp_path, header=HEADER + ",no\x1bte", rows=[r + ",x" for r in ROWS]), "column 7 name")


@pytest.mark.parametrize(
    ("text", "match"),
    [("a\u202eb", r"U\+202E"), ("a\x00b", r"U\+0000"), ("a\nb", r"U\+000A"), ("x" * 1001, "1001 characters")],
)
def test_check_text(text: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        check_text(text)


def test_multiline_text_allows_newlines_but_not_nul() -> None:
    assert check_text("1 Main St\nTown", multiline=True) == "1 Main St\nTown"
    with pytest.raises(InputError, match=r"U\+0000"):
        check_text("1 Main St\x00", multiline=True)


def test_loads_json_keeps_ordinary_documents() -> None:
    assert loads_json(json.dumps(SIDECAR)) == SIDECAR


def test_error_names_sidecar_not_traceback_for_string_with_brackets() -> None:
    # brackets inside strings do not count as nesting
    doc = {"label": "[" * 1000}
    assert loads_json(json.dumps(doc)) == doc


def test_recording_error_is_one_line(tmp_path: Path) -> None:
    rows = [*ROWS[:2], "0.02,1.5,1.5,1.7,0,0", '0.03,"1.5\n2",1.5,1.7,0,0']
    with pytest.raises(RecordingError) as info:
        read_recording(write(tmp_path, rows))
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ('{"a": "x\\ud800"}', "a character 2"),
        ('{"a": [1, {"b": "\\udfff"}]}', "a[1].b character 1"),
        ('{"\\ud800": 1}', "a key in the document"),
        ('["\\ude00\\ud83d"]', "[0] character 1"),  # a pair in the wrong order is two lone halves
    ],
)
def test_json_with_a_lone_surrogate_is_refused_naming_where(text: str, where: str) -> None:
    with pytest.raises(InputError, match="lone UTF-16 surrogate") as info:
        loads_json(text)
    assert where in str(info.value)


def test_json_with_a_surrogate_pair_is_one_character() -> None:
    assert loads_json('{"a": "\\ud83d\\ude00"}') == {"a": "\U0001f600"}
