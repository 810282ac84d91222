"""Converting the real IMU-TK (Xsens) and imucal (Ferraris) data sets to calbench-recording/1."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from api.cli import main
from bench.convert import read_imu_tk, read_imucal, read_imucal_annotated
from bench.convert.imu_tk import XSENS_G_LOCAL_M_S2
from bench.estimation.windows import detect_static_windows, window_stats, windows_from_segments
from bench.recording import read_recording

XSENS = {"channel_unit": "count", "gyro_unit": "count", "g_local_m_s2": XSENS_G_LOCAL_M_S2}
XSENS_CLI = ["--channel-unit", "count", "--gyro-unit", "count", "--g-local-m-s2", str(XSENS_G_LOCAL_M_S2)]


@pytest.fixture(scope="module")
def real(real_dir: Path) -> Path:
    return real_dir


def _lines(path: Path) -> int:
    return sum(1 for line in path.read_text().splitlines() if line.strip())


def test_imu_tk_ascii_pair_to_recording_and_back(
    real: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = real / "imu_tk-xsens"
    out = tmp_path / "xsens.csv"
    assert (
        main(
            [
                "convert",
                "imu_tk",
                str(src / "xsens_acc.mat"),
                str(src / "xsens_gyro.mat"),
                "-o",
                str(out),
                *XSENS_CLI,
            ]
        )
        == 0
    )
    assert "51175 samples" in capsys.readouterr().out
    rec = read_recording(out)
    acc = np.loadtxt(src / "xsens_acc.mat")
    gyro = np.loadtxt(src / "xsens_gyro.mat")
    assert rec.n_samples == _lines(src / "xsens_acc.mat") == 51175
    np.testing.assert_array_equal(rec.t_s, acc[:, 0])
    np.testing.assert_array_equal(rec.accel_raw, acc[:, 1:])
    np.testing.assert_array_equal(np.array(rec.extra_columns["gyr_z_counts"], dtype=float), gyro[:, 3])
    sc = rec.sidecar
    assert (sc.channel_unit, sc.table, sc.segments, sc.gyro_unit) == ("count", None, None, None)
    assert sc.extra["extra_column_units"] == {
        "gyr_x_counts": "count",
        "gyr_y_counts": "count",
        "gyr_z_counts": "count",
    }


def test_imu_tk_joined_csv_gives_the_same_recording(real: Path) -> None:
    a = read_imu_tk(real / "imu_tk-xsens/xsens_acc.mat", real / "imu_tk-xsens/xsens_gyro.mat", **XSENS)
    b = read_imu_tk(real / "imu_tk-xsens/xsens_mti_raw_counts.csv", channel_unit=None, g_local_m_s2=9.81744)
    np.testing.assert_array_equal(a.t_s, b.t_s)
    np.testing.assert_array_equal(a.accel_raw, b.accel_raw)
    assert a.extra_columns == b.extra_columns


def test_xsens_static_windows_agree_with_imu_tk_detector(real: Path) -> None:
    """The README reproduces IMU-TK's detector: 38 intervals, the first the 0.5–51.9 s initial rest."""
    rec = read_imu_tk(real / "imu_tk-xsens/xsens_mti_raw_counts.csv", channel_unit=None, g_local_m_s2=9.81744)
    found = detect_static_windows(rec.t_s, rec.accel_raw)
    assert 34 <= len(found) <= 42
    assert found[0].start_s < 1.0 and abs(found[0].end_s - 51.9) < 1.0
    assert min(w.end_s - w.start_s for w in found[1:]) > 2.0


def test_imu_tk_refuses_mismatched_time(real: Path, tmp_path: Path) -> None:
    gyro = np.loadtxt(real / "imu_tk-xsens/xsens_gyro.mat")[:1000]
    acc = np.loadtxt(real / "imu_tk-xsens/xsens_acc.mat")[:1000]
    gyro[500, 0] += 1e-3
    np.savetxt(tmp_path / "g.mat", gyro)
    np.savetxt(tmp_path / "a.mat", acc)
    with pytest.raises(
        ValueError, match=r"g\.mat: time stamps differ from a\.mat \(first differing row 501\)"
    ):
        read_imu_tk(tmp_path / "a.mat", tmp_path / "g.mat", **XSENS)
    acc[10, 2] = np.nan
    np.savetxt(tmp_path / "a.mat", acc)
    with pytest.raises(ValueError, match=r"a\.mat \(data row 11\): non-finite"):
        read_imu_tk(tmp_path / "a.mat", channel_unit="count", g_local_m_s2=XSENS_G_LOCAL_M_S2)


def test_imucal_session_with_sections(real: Path, tmp_path: Path) -> None:
    src = real / "imucal-ferraris"
    out = tmp_path / "ferraris.csv"
    args = [
        "convert",
        "imucal",
        str(src / "example_ferraris_session.csv"),
        "-o",
        str(out),
        "--sample-rate-hz",
        "102.4",
    ]
    assert main(args) == 0
    rec = read_recording(out)
    assert rec.n_samples == _lines(src / "example_ferraris_session.csv") - 1 == 10376
    raw = np.loadtxt(src / "example_ferraris_session.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(rec.accel_raw, raw[:, 4:7])
    assert rec.gyro_raw is not None
    np.testing.assert_array_equal(rec.gyro_raw, raw[:, 1:4])
    np.testing.assert_allclose(rec.t_s, raw[:, 0] / 102.4, rtol=0, atol=1e-12)
    assert (rec.sidecar.channel_unit, rec.sidecar.gyro_unit, rec.sidecar.sample_rate_hz) == (
        "m/s2",
        "deg/s",
        102.4,
    )
    sections = json.loads((src / "example_ferraris_session_list.json").read_text())
    segs = {s.label: s for s in rec.sidecar.segments or ()}
    assert set(segs) == set(sections)
    for label, v in sections.items():
        assert segs[label].start_s == pytest.approx(v["start"] / 102.4)
        assert segs[label].end_s == pytest.approx((v["end"] - 1) / 102.4)
    assert {label: s.nominal_up for label, s in segs.items() if s.nominal_up} == {
        "x_p": "+x",
        "x_a": "-x",
        "y_p": "+y",
        "y_a": "-y",
        "z_p": "+z",
        "z_a": "-z",
    }
    # README: |a| = 9.23–10.48 m/s² in the six poses before calibration
    six = [w for w in windows_from_segments(rec.t_s, rec.sidecar.segments or ()) if w.nominal_up]
    norms = np.linalg.norm(window_stats(rec.t_s, rec.accel_raw, None, None, six).mean, axis=1)
    assert norms.min() == pytest.approx(9.23, abs=0.01) and norms.max() == pytest.approx(10.48, abs=0.01)


def test_imucal_annotated_session_in_counts(real: Path, tmp_path: Path) -> None:
    src = real / "imucal-ferraris/annotated_session.csv"
    rec = read_imucal_annotated(src, 204.8)
    assert rec.n_samples == _lines(src) - 1 == 9414
    assert rec.sidecar.channel_unit == "count" and rec.gyro_raw is None
    segs = rec.sidecar.segments or ()
    assert [s.label for s in segs] == ["x_p", "x_a", "y_p", "y_a", "z_p", "z_a", "x_rot", "y_rot", "z_rot"]
    rows = [line.split(",") for line in src.read_text().splitlines()[1:]]
    first_x_a = next(r for r in rows if r[0] == "x_a")
    i = int(first_x_a[1])
    np.testing.assert_array_equal(rec.accel_raw[i], [float(x) for x in first_x_a[2:5]])
    assert rec.extra_columns["gyr_x_counts"][i] == str(int(float(first_x_a[5])))
    out = tmp_path / "ann.csv"
    assert main(["convert", "imucal", str(src), "-o", str(out), "--sample-rate-hz", "204.8"]) == 0
    back = read_recording(out)
    np.testing.assert_array_equal(back.accel_raw, rec.accel_raw)
    np.testing.assert_array_equal(back.t_s, rec.t_s)
    assert back.extra_columns == rec.extra_columns
    assert back.sidecar == rec.sidecar


def test_imucal_labels_that_contradict_the_data_are_refused(real: Path, tmp_path: Path) -> None:
    src = real / "imucal-ferraris"
    sections = json.loads((src / "example_ferraris_session_list.json").read_text())
    sections["x_p"], sections["x_a"] = sections["x_a"], sections["x_p"]
    (tmp_path / "swapped.json").write_text(json.dumps(sections))
    with pytest.raises(ValueError, match=r"part 'x_.' should read gravity on [+-]x"):
        read_imucal([src / "example_ferraris_session.csv", tmp_path / "swapped.json"], 102.4)


def test_cli_bad_input_exits_2_with_one_line(
    real: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = real / "imucal-ferraris/annotated_session.csv"
    assert main(["convert", "imucal", str(src), "-o", str(tmp_path / "a.csv")]) == 2
    assert "--sample-rate-hz is required" in capsys.readouterr().err
    assert main(["convert", "imucal", str(tmp_path / "nope.csv"), "-o", str(tmp_path / "a.csv")]) == 2
    assert "nope.csv: no such file" in capsys.readouterr().err
    (tmp_path / "a.csv").write_text("keep me")
    assert (
        main(["convert", "imucal", str(src), "-o", str(tmp_path / "a.csv"), "--sample-rate-hz", "204.8"]) == 2
    )
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "a.csv").read_text() == "keep me"
    assert main(["convert", "imu_tk", str(src), "-o", str(tmp_path / "b.csv"), "--g-local-m-s2", "9.81"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "annotated_session.csv" in err


def _other_imu(tmp_path: Path) -> tuple[Path, Path, np.ndarray, np.ndarray]:
    """IMU-TK files of another IMU: 200 Hz, accelerometer in m/s², gyro in rad/s."""
    rng = np.random.default_rng(8)
    n = 2000
    t = 0.005 * np.arange(n)
    acc = np.column_stack([t, np.tile([0.1, -0.2, 9.79], (n, 1)) + rng.normal(0, 0.01, (n, 3))])
    gyro = np.column_stack([t, rng.normal(0, 0.002, (n, 3))])
    np.savetxt(tmp_path / "acc.txt", acc)
    np.savetxt(tmp_path / "gyr.txt", gyro)
    return tmp_path / "acc.txt", tmp_path / "gyr.txt", acc, gyro


def test_imu_tk_writes_only_what_it_knows(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, g, acc, gyro = _other_imu(tmp_path)
    out = tmp_path / "other.csv"
    args = ["convert", "imu_tk", str(a), str(g), "-o", str(out)]
    assert main([*args, "--channel-unit", "m/s2", "--gyro-unit", "rad/s", "--g-local-m-s2", "9.80"]) == 0
    assert "channel_unit m/s2" in capsys.readouterr().out
    rec = read_recording(out)
    sc = rec.sidecar
    assert (sc.channel_unit, sc.gyro_unit, sc.g_local_m_s2) == ("m/s2", "rad/s", 9.80)
    assert sc.sample_rate_hz == pytest.approx(200.0, rel=1e-9)  # from the time stamps, not 100 Hz
    assert sc.unit_model is None and sc.unit_serial == "unknown"
    assert sc.procedure is None
    assert "dataset" not in sc.extra["source"]  # type: ignore[operator]
    side = json.loads(out.with_suffix(".json").read_text())
    assert "Xsens" not in json.dumps(side) and "Tedaldi" not in json.dumps(side)
    assert rec.gyro_raw is not None
    np.testing.assert_allclose(rec.gyro_raw, gyro[:, 1:], rtol=1e-12)
    np.testing.assert_allclose(rec.accel_raw, acc[:, 1:], rtol=1e-12)
    assert not rec.extra_columns


def test_imu_tk_asks_for_what_the_files_do_not_say(
    real: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a, g, _, _ = _other_imu(tmp_path)
    base = ["convert", "imu_tk", str(a), str(g), "-o", str(tmp_path / "o.csv")]
    cases = [
        ([], "--channel-unit is required"),
        (["--channel-unit", "m/s2"], "--gyro-unit is required"),
        (["--channel-unit", "m/s2", "--gyro-unit", "rad/s"], "--g-local-m-s2 is required"),
        # the data's magnitude contradicts a declared unit
        (["--channel-unit", "g", "--gyro-unit", "rad/s", "--g-local-m-s2", "9.8"], "not in g"),
    ]
    for extra, msg in cases:
        assert main([*base, *extra]) == 2, extra
        err = capsys.readouterr().err.strip()
        assert msg in err and err.count("\n") == 0, err
    assert not (tmp_path / "o.csv").exists()
    # the joined CSV's header names counts: a different unit contradicts it
    with pytest.raises(ValueError, match=r"header names the accelerometer in counts, not m/s2"):
        read_imu_tk(real / "imu_tk-xsens/xsens_mti_raw_counts.csv", channel_unit="m/s2", g_local_m_s2=9.81)


def test_imu_tk_credits_a_data_set_only_when_told(real: Path) -> None:
    rec = read_imu_tk(
        real / "imu_tk-xsens/xsens_acc.mat",
        real / "imu_tk-xsens/xsens_gyro.mat",
        **XSENS,
        unit_model="Xsens MTi",
        dataset="IMU-TK test data (Tedaldi, Pretto, Menegatti, ICRA 2014), Xsens MTi",
    )
    assert rec.sidecar.unit_model == "Xsens MTi"
    assert rec.sidecar.extra["source"]["dataset"].startswith("IMU-TK test data")  # type: ignore[index]
    assert rec.sidecar.sample_rate_hz == pytest.approx(100.0, rel=1e-3)
