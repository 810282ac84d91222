"""Property-based fuzzing of the input layer, the recording reader and the sidecar.

Properties: every input is either accepted with the value a different formulation gives, or
refused with the package's own error (``InputError``/``RecordingError``, one line); nothing
else escapes. Kept fast here (``CALBENCH_FUZZ_EXAMPLES``, default 40 per property);
``make fuzz`` runs them with thousands of examples.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import string
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from bench.inputs import MAX_JSON_DEPTH, InputError, check_text, loads_json, parse_decimal
from bench.recording import RecordingError, read_recording
from bench.recording.sidecar import parse_sidecar
from tests.bench.recording.test_recording_errors import HEADER, ROWS, SIDECAR

EXAMPLES = int(os.environ.get("CALBENCH_FUZZ_EXAMPLES", "40"))
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
ASCII_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
NUMBERISH = st.text(alphabet=string.digits + "+-.eE_ \t" + "١٢１\u00a0xn", max_size=30)


@FUZZ
@given(st.one_of(NUMBERISH, st.text(max_size=30)))
def test_parse_decimal_accepts_exactly_the_ascii_grammar(text: str) -> None:
    s = text.strip(" \t")
    try:
        x = parse_decimal(text)
    except InputError:
        grammatical = ASCII_DECIMAL.fullmatch(s) is not None
        assert not grammatical or not math.isfinite(float(s)) or len(s) > 100
        return
    assert ASCII_DECIMAL.fullmatch(s) and s.isascii()
    assert x == float(s) and math.isfinite(x)


@FUZZ
@given(st.floats(allow_nan=False, allow_infinity=False))
def test_every_finite_double_round_trips(x: float) -> None:
    assert parse_decimal(repr(x)) == x
    assert parse_decimal(f"{x:.17e}") == x


JSON_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**18), 10**18)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=10),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=5), inner, max_size=4),
    max_leaves=20,
)


@FUZZ
@given(JSON_VALUES)
def test_loads_json_round_trips_ordinary_documents(value: Any) -> None:
    assert loads_json(json.dumps(value)) == value


@FUZZ
@given(st.text(alphabet='[]{}"\\,:0123456789eE.-NaInfity ', max_size=200))
def test_loads_json_refuses_cleanly(text: str) -> None:
    with contextlib.suppress(ValueError):  # InputError or json.JSONDecodeError, both ValueErrors
        loads_json(text)


@FUZZ
@given(st.integers(1, 3 * MAX_JSON_DEPTH), st.sampled_from("[{"))
def test_nesting_limit_is_exact(depth: int, opener: str) -> None:
    nested_objects = '{"k":' * (depth - 1) + "{}" + "}" * (depth - 1)
    text = "[" * depth + "]" * depth if opener == "[" else nested_objects
    if depth > MAX_JSON_DEPTH:
        with pytest.raises(InputError, match="nested deeper"):
            loads_json(text)
    else:
        loads_json(text)


@FUZZ
@given(st.text(max_size=60))
def test_check_text_refuses_exactly_controls_and_bidi(text: str) -> None:
    bidi = set("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069\u200e\u200f\u061c")
    bad = any(ch in bidi or ord(ch) < 0x20 or 0x7F <= ord(ch) <= 0x9F for ch in text)
    if bad:
        with pytest.raises(InputError):
            check_text(text)
    else:
        assert check_text(text) == text


def _write(tmp: Path, csv_text: str, side: Any) -> Path:
    csv = tmp / "run.csv"
    csv.write_bytes(csv_text.encode("utf-8", "surrogateescape"))
    (tmp / "run.json").write_text(side if isinstance(side, str) else json.dumps(side))
    return csv


def _read_or_refuse(path: Path) -> Any:
    try:
        return read_recording(path)
    except RecordingError as exc:
        assert "\n" not in str(exc) and path.stem in str(exc)
        return None


BASE_CSV = "\n".join([HEADER, *ROWS]) + "\n"
FIELD = st.one_of(
    st.sampled_from(
        ["1_0", "١٢", "１", "nan", "inf", "1e999", "", "-", "0x1", "1" * 200, "\x00", '"', "\u202e"]
    ),
    st.text(max_size=8),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
)


@FUZZ
@given(row=st.integers(0, 3), col=st.integers(0, 5), field=FIELD)
def test_one_bad_field_is_read_exactly_or_refused(tmp_path: Path, row: int, col: int, field: str) -> None:
    rows = [r.split(",") for r in ROWS]
    rows[row][col] = field
    csv_text = "\n".join([HEADER, *(",".join(r) for r in rows)]) + "\n"
    rec = _read_or_refuse(_write(tmp_path, csv_text, SIDECAR))
    if rec is None:
        return
    expected = np.array([[float(v) for v in r] for r in rows])  # a different formulation
    got = np.column_stack([rec.t_s, rec.accel_raw, rec.table_deg])
    np.testing.assert_array_equal(got, expected)
    assert ASCII_DECIMAL.fullmatch(field.strip(" \t"))


@FUZZ
@given(st.binary(max_size=40), st.integers(0, len(BASE_CSV)))
def test_inserted_bytes_are_read_or_refused(tmp_path: Path, junk: bytes, at: int) -> None:
    raw = BASE_CSV.encode()[:at] + junk + BASE_CSV.encode()[at:]
    _read_or_refuse(_write(tmp_path, raw.decode("utf-8", "surrogateescape"), SIDECAR))


def _sidecar_paths(obj: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix] if prefix else []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _sidecar_paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _sidecar_paths(v, (*prefix, i))
    return out


PATHS = _sidecar_paths(SIDECAR)


@FUZZ
@given(st.sampled_from(PATHS), JSON_VALUES)
def test_sidecar_value_replaced_is_parsed_or_refused(path: tuple[Any, ...], value: Any) -> None:
    side = json.loads(json.dumps(SIDECAR))
    d = side
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value
    try:
        sc = parse_sidecar(side, "run.json")
    except RecordingError as exc:
        assert "\n" not in str(exc)
        return
    assert math.isfinite(sc.sample_rate_hz) and sc.sample_rate_hz > 0
    assert sc.unit_serial.strip() and check_text(sc.unit_serial) == sc.unit_serial


@FUZZ
@given(st.text(max_size=300))
def test_sidecar_text_is_read_or_refused(tmp_path: Path, text: str) -> None:
    assume(text.strip())
    _read_or_refuse(_write(tmp_path, BASE_CSV, text))
