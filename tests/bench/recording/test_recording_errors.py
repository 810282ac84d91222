"""Every validation rule of docs/recording-format.md: an error naming the file, the row or key,
and the rule."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

from bench.recording import RecordingError, read_recording
from bench.recording.sidecar import sidecar_to_dict

SIDECAR: dict[str, Any] = {
    "format": "calbench-recording/1",
    "unit": {"serial": "SN-7", "model": "triad"},
    "channel_unit": "V",
    "sample_rate_hz": 100.0,
    "g_local_m_s2": 9.81535,
    "table": {
        "axes": [{"name": "outer", "axis": [0, 0, 1]}, {"name": "inner", "axis": [1, 0, 0]}],
        "mount_rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
        "lever_arm_m": [0, 0, 0],
    },
    "segments": [{"start_s": 0.0, "end_s": 0.01, "label": "pos01"}],
}
HEADER = "t,ax,ay,az,table_1,table_2"
ROWS = ["0.00,1.5,1.5,1.7,0,0", "0.01,1.5,1.5,1.7,0,0", "0.02,1.5,1.5,1.7,0,0", "0.03,1.5,1.5,1.7,0,0"]


def write(tmp_path: Path, rows: list[str] | None = None, header: str = HEADER, **changes: Any) -> Path:
    side = copy.deepcopy(SIDECAR)
    for dotted, value in changes.items():
        *parents, last = dotted.split("__")
        d = side
        for p in parents:
            d = d[p]
        if value is DELETE:
            del d[last]
        else:
            d[last] = value
    csv = tmp_path / "run.csv"
    csv.write_text("\n".join([header, *(ROWS if rows is None else rows)]) + "\n")
    (tmp_path / "run.json").write_text(json.dumps(side))
    return csv


DELETE = object()


def expect(path: Path, *parts: str) -> RecordingError:
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    msg = str(info.value)
    for p in parts:
        assert p in msg, f"{p!r} not in {msg!r}"
    return info.value


def test_valid_file_reads(tmp_path: Path) -> None:
    assert read_recording(write(tmp_path)).n_samples == 4


# --- CSV rules -----------------------------------------------------------------------------


@pytest.mark.parametrize("column", ["t", "ax", "az", "table_2"])
def test_missing_required_column(tmp_path: Path, column: str) -> None:
    header = ",".join(c for c in HEADER.split(",") if c != column)
    rows = [
        ",".join(v for c, v in zip(HEADER.split(","), r.split(","), strict=True) if c != column) for r in ROWS
    ]
    e = expect(
        write(tmp_path, rows, header), "run.csv", "line 1", f"column '{column}'", "missing required column"
    )
    assert e.column == column


@pytest.mark.parametrize(
    "bad,column,what",
    [
        ("abc", "ay", "not a number: 'abc'"),
        ("nan", "ay", "non-finite value 'nan'"),
        ("inf", "table_1", "non-finite value 'inf'"),
        ("-Infinity", "ax", "non-finite"),
        ("", "az", "missing value (empty field)"),
        ("", "t", "missing value"),
    ],
)
def test_bad_value_names_row_line_and_column(tmp_path: Path, bad: str, column: str, what: str) -> None:
    cols = HEADER.split(",")
    fields = ROWS[2].split(",")
    fields[cols.index(column)] = bad
    rows = [*ROWS[:2], ",".join(fields), ROWS[3]]
    e = expect(write(tmp_path, rows), "run.csv", "data row 3", "line 4", f"column '{column}'", what)
    assert (e.row, e.line) == (3, 4)


def test_time_must_increase(tmp_path: Path) -> None:
    rows = [ROWS[0], ROWS[1], ROWS[1].replace("0.01", "0.005", 1), ROWS[3]]
    expect(write(tmp_path, rows), "run.csv", "data row 3", "line 4", "column 't'", "strictly increasing")
    rows = [ROWS[0], ROWS[1], ROWS[1], ROWS[3]]
    expect(write(tmp_path, rows), "data row 3", "does not increase")


def test_wrong_field_count(tmp_path: Path) -> None:
    expect(
        write(tmp_path, [*ROWS[:3], ROWS[3] + ",9"]),
        "run.csv",
        "data row 4",
        "line 5",
        "7 fields, expected 6",
    )
    expect(write(tmp_path, [*ROWS[:1], "0.01,1.5,1.5"]), "data row 2", "3 fields, expected 6")


def test_blank_line_inside_data_is_not_skipped(tmp_path: Path) -> None:
    expect(write(tmp_path, [ROWS[0], "", *ROWS[1:]]), "run.csv", "line 3", "blank line inside the data")


def test_no_rows_and_empty_file(tmp_path: Path) -> None:
    expect(write(tmp_path, []), "run.csv", "no data rows")
    (tmp_path / "run.csv").write_text("")
    expect(tmp_path / "run.csv", "run.csv", "line 1", "empty")


def test_duplicate_column(tmp_path: Path) -> None:
    expect(write(tmp_path, [r + ",1" for r in ROWS], HEADER + ",ax"), "line 1", "column 'ax'", "duplicate")


def test_table_columns_must_match_axes(tmp_path: Path) -> None:
    expect(write(tmp_path, [r + ",0" for r in ROWS], HEADER + ",table_3"), "column 'table_3'", "2 table axes")
    rows = [",".join(r.split(",")[:4]) for r in ROWS]
    expect(write(tmp_path, rows, "t,ax,ay,az"), "column 'table_1'", "missing required column")
    expect(write(tmp_path, table=DELETE), "column 'table_1'", "has no 'table'")


def test_gyro_columns_need_gyro_unit_and_come_together(tmp_path: Path) -> None:
    rows = [r + ",1,2,3" for r in ROWS]
    expect(write(tmp_path, rows, HEADER + ",gx,gy,gz"), "run.json", "key 'gyro_unit'", "gyro columns")
    rows = [r + ",1,2" for r in ROWS]
    expect(write(tmp_path, rows, HEADER + ",gx,gy", gyro_unit="deg/s"), "column 'gz'", "together")
    assert (
        read_recording(
            write(tmp_path, [r + ",1,2,3" for r in ROWS], HEADER + ",gx,gy,gz", gyro_unit="rad/s")
        ).gyro_raw
        is not None
    )


def test_no_row_is_ever_dropped(tmp_path: Path) -> None:
    rows = [f"{i * 0.01:.2f},1.5,1.5,1.7,0,0" for i in range(1000)]
    assert read_recording(write(tmp_path, rows)).n_samples == 1000
    rows[617] = rows[617].replace("1.7", "1.7x")
    expect(write(tmp_path, rows), "data row 618", "line 619", "column 'az'", "'1.7x'")


# --- sidecar rules -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "change,key,what",
    [
        ({"format": DELETE}, "format", "missing required key"),
        ({"format": "calbench-recording/2"}, "format", "unknown format 'calbench-recording/2'"),
        ({"unit": DELETE}, "unit", "missing required key"),
        ({"unit__serial": DELETE}, "unit.serial", "missing required key"),
        ({"channel_unit": DELETE}, "channel_unit", "missing required key"),
        ({"channel_unit": "mV"}, "channel_unit", "'mV' is not one of V, count, m/s2, g"),
        ({"gyro_unit": "rpm"}, "gyro_unit", "'rpm' is not one of rad/s, deg/s"),
        ({"sample_rate_hz": DELETE}, "sample_rate_hz", "missing required key"),
        ({"sample_rate_hz": "100"}, "sample_rate_hz", "expected a number"),
        ({"sample_rate_hz": -5}, "sample_rate_hz", "positive"),
        ({"g_local_m_s2": DELETE}, "g_local_m_s2", "missing required key"),
        ({"g_local_m_s2": 1.0}, "g_local_m_s2", "outside 9.7–9.9"),
        ({"table__axes": DELETE}, "table.axes", "missing required key"),
        ({"table__axes": []}, "table.axes", "non-empty list"),
        (
            {"table__axes": [{"name": "a", "axis": [0, 0, 1.01]}, {"name": "b", "axis": [1, 0, 0]}]},
            "table.axes[0].axis",
            "unit vector",
        ),
        (
            {"table__axes": [{"name": "a", "axis": [0, 0, 1]}, {"name": "b", "axis": [1, 0]}]},
            "table.axes[1].axis",
            "list of 3 numbers",
        ),
        (
            {"table__mount_rotation": [[1, 0, 0], [0, 1, 0], [0, 0, -1]]},
            "table.mount_rotation",
            "determinant +1",
        ),
        (
            {"table__mount_rotation": [[1, 0.01, 0], [0, 1, 0], [0, 0, 1]]},
            "table.mount_rotation",
            "orthonormal",
        ),
        ({"table__mount_rotation": [[1, 0, 0], [0, 1, 0]]}, "table.mount_rotation", "3x3"),
        ({"table__lever_arm_m": [0, 0, None]}, "table.lever_arm_m[2]", "expected a number"),
        ({"table__encoder_resolution_deg": 0}, "table.encoder_resolution_deg", "expected > 0"),
        ({"table__encoder_resolution_deg": -1e-4}, "table.encoder_resolution_deg", "expected > 0"),
        ({"table__encoder_resolution_deg": 2.0}, "table.encoder_resolution_deg", "at most 1°"),
        ({"table__encoder_resolution_deg": "1e-4"}, "table.encoder_resolution_deg", "expected a number"),
        (
            {
                "segments": [
                    {"start_s": 0.0, "end_s": 0.02, "label": "a"},
                    {"start_s": 0.01, "end_s": 0.03, "label": "b"},
                ]
            },
            "segments[1]",
            "overlap",
        ),
        (
            {"segments": [{"start_s": 0.0, "end_s": 0.5, "label": "a"}]},
            "segments[0]",
            "outside the recording",
        ),
        ({"segments": [{"start_s": 0.02, "end_s": 0.01}]}, "segments[0]", "not after start_s"),
        ({"segments": [{"end_s": 0.01}]}, "segments[0].start_s", "missing required key"),
        (
            {"segments": [{"start_s": 0.0, "end_s": 0.01, "nominal_up": "up"}]},
            "segments[0].nominal_up",
            "'up' is not one of +x, -x",
        ),
    ],
)
def test_sidecar_rule_names_file_and_key(tmp_path: Path, change: dict[str, Any], key: str, what: str) -> None:
    e = expect(write(tmp_path, **change), "run.json", f"key '{key}'", what)
    assert e.key == key


def test_sidecar_not_json(tmp_path: Path) -> None:
    csv = write(tmp_path)
    (tmp_path / "run.json").write_text('{"format": "calbench-recording/1",')
    expect(csv, "run.json", "not valid JSON")


def test_missing_sidecar_is_file_not_found(tmp_path: Path) -> None:
    csv = write(tmp_path)
    (tmp_path / "run.json").unlink()
    with pytest.raises(FileNotFoundError, match=r"run\.json"):
        read_recording(csv)


def test_hand_held_recording_with_nominal_up(tmp_path: Path) -> None:
    rows = [",".join(r.split(",")[:4]) for r in ROWS]
    segs = [
        {"start_s": 0.0, "end_s": 0.01, "label": "zp", "nominal_up": "+z"},
        {"start_s": 0.02, "end_s": 0.03, "label": "zm", "nominal_up": "-z"},
    ]
    rec = read_recording(write(tmp_path, rows, "t,ax,ay,az", table=DELETE, segments=segs))
    assert rec.table_deg is None and rec.table_rad_unwrapped() is None
    assert [s.nominal_up for s in rec.sidecar.segments or ()] == ["+z", "-z"]


def test_encoder_resolution_is_optional_and_written_back(tmp_path: Path) -> None:
    """Without the key the step is not declared (older recordings); with it, it is read and kept."""
    plain = read_recording(write(tmp_path)).sidecar
    assert plain.table is not None and plain.table.encoder_resolution_deg is None
    assert "encoder_resolution_deg" not in json.dumps(sidecar_to_dict(plain))
    nulled = read_recording(write(tmp_path, table__encoder_resolution_deg=None)).sidecar
    assert nulled.table is not None and nulled.table.encoder_resolution_deg is None
    sc = read_recording(write(tmp_path, table__encoder_resolution_deg=1e-4)).sidecar
    assert sc.table is not None and sc.table.encoder_resolution_deg == 1e-4
    table = sidecar_to_dict(sc)["table"]
    assert isinstance(table, dict) and table["encoder_resolution_deg"] == 1e-4
