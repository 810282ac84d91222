"""Reading and writing calbench-recording/1: round trips, the incremental writer, resume after a crash."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bench.recording import (
    Recording,
    RecordingError,
    RecordingWriter,
    Segment,
    Sidecar,
    TableAxis,
    TableGeometry,
    read_recording,
    read_sidecar,
    write_recording,
)

TABLE = TableGeometry(
    axes=(
        TableAxis("outer", (0.0, 0.0, 1.0)),
        TableAxis("middle", (1.0, 0.0, 0.0)),
        TableAxis("inner", (0.0, 0.0, 1.0)),
    ),
    lever_arm_m=(0.06, 0.0, -0.015),
)


def make_sidecar(table: TableGeometry | None = TABLE, **kw: object) -> Sidecar:
    args: dict[str, object] = {
        "unit_serial": "SN-1",
        "channel_unit": "V",
        "sample_rate_hz": 100.0,
        "g_local_m_s2": 9.81535,
        "unit_model": "triad",
        "procedure": "static-12",
        "table": table,
    }
    args.update(kw)
    return Sidecar(**args)  # type: ignore[arg-type]


def make_recording(
    n: int = 500, seed: int = 1, table: bool = True, temp: bool = True, gyro: bool = False
) -> Recording:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01 + rng.uniform(0, 1e-4, n)
    return Recording(
        sidecar=make_sidecar(
            TABLE if table else None,
            gyro_unit="deg/s" if gyro else None,
            segments=(Segment(0.05, 0.1, "pos01"), Segment(0.12, 0.18, "pos02")),
        ),
        t_s=t,
        accel_raw=1.5 + rng.normal(0, 0.1, (n, 3)) / 3.0,
        table_deg=rng.uniform(-180, 180, (n, 3)) if table else None,
        temp_c=25 + rng.normal(0, 1, n) if temp else None,
        gyro_raw=rng.normal(0, 1e3, (n, 3)) if gyro else None,
    )


def assert_same(a: Recording, b: Recording) -> None:
    for name in ("t_s", "accel_raw", "table_deg", "temp_c", "gyro_raw"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)
    assert a.sidecar == b.sidecar
    assert a.extra_columns == b.extra_columns


@pytest.mark.parametrize("table,temp,gyro", [(True, True, False), (False, False, True), (True, False, True)])
def test_round_trip_is_bit_exact(tmp_path: Path, table: bool, temp: bool, gyro: bool) -> None:
    rec = make_recording(table=table, temp=temp, gyro=gyro)
    write_recording(rec, tmp_path / "run.csv")
    back = read_recording(tmp_path / "run.csv")
    assert_same(rec, back)
    assert back.source == str(tmp_path / "run.csv")


def test_unknown_columns_and_keys_survive_a_round_trip(tmp_path: Path) -> None:
    csv_text = 'ax,t,note,ay,az\n1.0,0.0,"a, b",2.0,3.0\n1.5,0.01,x,2.5,3.5\n'
    (tmp_path / "r.csv").write_text(csv_text)
    side = {
        "format": "calbench-recording/1",
        "unit": {"serial": "S", "owner": "lab 3"},
        "channel_unit": "g",
        "sample_rate_hz": 100,
        "g_local_m_s2": 9.81,
        "operator": "jd",
        "segments": [{"start_s": 0.0, "end_s": 0.01, "label": "a", "nominal_up": "-z", "note": 1}],
    }
    (tmp_path / "r.json").write_text(json.dumps(side))
    rec = read_recording(tmp_path / "r.csv")
    assert rec.extra_columns == {"note": ["a, b", "x"]}
    np.testing.assert_array_equal(rec.accel_raw, [[1.0, 2.0, 3.0], [1.5, 2.5, 3.5]])
    assert rec.sidecar.table is None and rec.table_deg is None
    assert rec.sidecar.extra["operator"] == "jd"
    assert rec.sidecar.segments == (Segment(0.0, 0.01, "a", "-z"),)
    write_recording(rec, tmp_path / "out.csv")
    again = json.loads((tmp_path / "out.json").read_text())
    assert again["operator"] == "jd" and again["unit"]["owner"] == "lab 3"
    assert again["segments"][0]["note"] == 1
    assert_same(rec, read_recording(tmp_path / "out.csv"))


def test_reads_the_independent_example_recording(independent_dir: Path) -> None:
    rec = read_recording(independent_dir / "example_static12.csv")
    assert rec.n_samples == 40800
    assert rec.sidecar.table is not None and len(rec.sidecar.table.axes) == 3
    assert rec.sidecar.segments is not None and len(rec.sidecar.segments) == 12
    assert rec.t_s[0] == 0.0 and rec.t_s[-1] == pytest.approx(407.99)
    np.testing.assert_array_equal(rec.accel_raw[0], [1.499130, 1.501053, 1.679123])


def test_optional_columns_may_have_empty_fields(tmp_path: Path) -> None:
    (tmp_path / "r.csv").write_text("t,ax,ay,az,temp\n0,1,2,3,25.5\n0.01,1,2,3,\n")
    (tmp_path / "r.json").write_text(
        json.dumps(
            {
                "format": "calbench-recording/1",
                "unit": {"serial": "S"},
                "channel_unit": "V",
                "sample_rate_hz": 100,
                "g_local_m_s2": 9.8,
            }
        )
    )
    rec = read_recording(tmp_path / "r.csv")
    assert rec.temp_c is not None
    assert rec.temp_c[0] == 25.5 and np.isnan(rec.temp_c[1])
    write_recording(rec, tmp_path / "o.csv")
    assert (tmp_path / "o.csv").read_text().splitlines()[2].endswith(",")


def test_writer_appends_blocks_and_rewrites_segments(tmp_path: Path) -> None:
    rec = make_recording(n=300)
    path = tmp_path / "live.csv"
    sc = make_sidecar(segments=None)
    with RecordingWriter(path, sc, n_axes=3, has_temp=True) as w:
        for i in range(0, 300, 64):
            sl = slice(i, i + 64)
            w.append(rec.t_s[sl], rec.accel_raw[sl], rec.table_deg[sl], rec.temp_c[sl])  # type: ignore[index]
            w.flush()
            assert read_recording(path).n_samples == min(i + 64, 300)
        w.add_segment(Segment(0.5, 1.0, "pos01"))
        w.add_segment(Segment(1.0, 2.0, "pos02"))
        assert read_sidecar(tmp_path / "live.json").segments == (
            Segment(0.5, 1.0, "pos01"),
            Segment(1.0, 2.0, "pos02"),
        )
        with pytest.raises(RecordingError, match="overlap"):
            w.add_segment(Segment(1.5, 2.5, "pos03"))
        with pytest.raises(ValueError, match="increase"):
            w.append([rec.t_s[-1]], [[1.0, 2.0, 3.0]], [[0.0, 0.0, 0.0]], [25.0])
        with pytest.raises(ValueError, match="non-finite"):
            w.append([10.0], [[1.0, np.inf, 3.0]], [[0.0, 0.0, 0.0]], [25.0])
        with pytest.raises(ValueError, match=r"shape"):
            w.append([10.0], [[1.0, 2.0]], [[0.0, 0.0, 0.0]], [25.0])
    back = read_recording(path)
    np.testing.assert_array_equal(back.accel_raw, rec.accel_raw)
    assert not list(tmp_path.glob(".*tmp")), "temporary sidecar left behind"


def test_writer_refuses_to_overwrite_and_checks_geometry(tmp_path: Path) -> None:
    write_recording(make_recording(n=20), tmp_path / "a.csv")
    with pytest.raises(FileExistsError):
        RecordingWriter(tmp_path / "a.csv", make_sidecar(), 3, True)
    with pytest.raises(ValueError, match="n_axes"):
        RecordingWriter(tmp_path / "b.csv", make_sidecar(), 2, True)


@pytest.mark.parametrize("torn", ["12.5,1.49", "12.5,1.49,1.5\x00\x00\x00", "\x00" * 100, ""])
def test_resume_cuts_a_torn_line_and_continues(tmp_path: Path, torn: str) -> None:
    rec = make_recording(n=200)
    path = tmp_path / "run.csv"
    write_recording(rec, path)
    with path.open("a", newline="") as f:
        f.write(torn)
    state = RecordingWriter.resume(path)
    assert state.n_rows == 200
    assert state.last_t_s == rec.t_s[-1]
    with state.writer as w:
        w.append([rec.t_s[-1] + 0.01], [[1.0, 2.0, 3.0]], [[10.0, 20.0, 30.0]], [24.0])
    back = read_recording(path)
    assert back.n_samples == 201
    np.testing.assert_array_equal(back.accel_raw[:200], rec.accel_raw)
    np.testing.assert_array_equal(back.table_deg[200], [10.0, 20.0, 30.0])  # type: ignore[index]


def test_resume_refuses_a_corrupt_complete_line(tmp_path: Path) -> None:
    path = tmp_path / "run.csv"
    write_recording(make_recording(n=10), path)
    before = path.read_bytes()
    with path.open("a") as f:
        f.write("garbage\n")
    with pytest.raises(RecordingError, match=r"data row 11, line 12"):
        RecordingWriter.resume(path)
    assert path.read_bytes() == before + b"garbage\n", "nothing may be cut from a file that is refused"


def test_resume_of_an_empty_recording(tmp_path: Path) -> None:
    path = tmp_path / "run.csv"
    RecordingWriter(path, make_sidecar(table=None), 0, False).close()
    state = RecordingWriter.resume(path)
    assert (state.n_rows, state.last_t_s) == (0, None)
    with state.writer as w:
        w.append([0.0, 0.01], [[1, 2, 3], [1, 2, 3]])
    assert read_recording(path).n_samples == 2
