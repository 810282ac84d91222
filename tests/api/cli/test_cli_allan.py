"""``calbench allan``: JSON fields, window choice, plot, and one-line errors on bad input."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import api.cli
from bench.recording import Recording, Segment, Sidecar, write_recording
from tests.support.noise import rate_random_walk, white

FS_HZ = 50.0
N_TRUE, K_TRUE = 2e-3, 2e-4  # m/s²·√s, m/s²/√s  →  τ* = √3·N/K = 17.3 s


def _write(
    tmp_path: Path,
    accel: np.ndarray,
    *,
    unit: str = "m/s2",
    t: np.ndarray | None = None,
    segments: tuple[Segment, ...] | None = None,
    name: str = "rec",
) -> Path:
    n = accel.shape[0]
    sc = Sidecar(
        unit_serial="SN-ALLAN", channel_unit=unit, sample_rate_hz=FS_HZ, g_local_m_s2=9.81, segments=segments
    )
    t_s = np.arange(n) / FS_HZ if t is None else t
    path = tmp_path / f"{name}.csv"
    write_recording(Recording(sidecar=sc, t_s=t_s, accel_raw=accel), path)
    return path


def main(argv: list[str]) -> int:
    """``calbench`` with only the allan subcommand loaded (the other modules are not under test)."""
    saved = api.cli.SUBCOMMANDS
    api.cli.SUBCOMMANDS = {"allan": saved["allan"]}
    try:
        return api.cli.main(argv)
    finally:
        api.cli.SUBCOMMANDS = saved


@pytest.fixture(scope="module")
def static_record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One hour at 50 Hz, white + rate random walk on each axis, z carries gravity."""
    rng = np.random.default_rng(77)
    n = 180_000
    a = white(rng, n, FS_HZ, N_TRUE, 3) + rate_random_walk(rng, n, FS_HZ, K_TRUE, 3)
    a[:, 2] += 9.81
    return _write(tmp_path_factory.mktemp("allan"), a)


def test_json_has_the_promised_fields_and_recovers_the_noise(
    static_record: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["allan", str(static_record), "--json", "--whole"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in (
        "unit",
        "channel_unit",
        "sample_rate_hz",
        "taus_s",
        "adev",
        "adev_lo",
        "adev_hi",
        "noise_terms",
        "dwell",
        "lines",
        "warnings",
    ):
        assert key in out
    assert out["unit"] == "SN-ALLAN" and out["channel_unit"] == "m/s2" and out["sample_rate_hz"] == FS_HZ
    m = len(out["taus_s"])
    assert set(out["adev"]) == {"ax", "ay", "az"} and all(len(v) == m for v in out["adev"].values())
    for ch in ("ax", "ay", "az"):
        lo, dev, hi = (np.array(out[k][ch]) for k in ("adev_lo", "adev", "adev_hi"))
        assert np.all(lo < dev) and np.all(dev < hi)
        terms = out["noise_terms"]["channels"][ch]
        assert terms["white_n"] == pytest.approx(N_TRUE, abs=4 * terms["white_n_sigma"])
        assert terms["rate_random_walk_k"] == pytest.approx(K_TRUE, rel=0.4)
    assert out["dwell"]["dwell_s"] == pytest.approx(math.sqrt(3) * N_TRUE / K_TRUE, rel=0.35)
    assert out["dwell"]["floor_reached"] is True
    assert "dwell" in out["dwell"]["reason"]
    assert out["lines"] == [] and out["lines_removed"] is False


def test_lines_are_reported_and_kept_out_of_the_noise_terms(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 0.5 Hz line on ax and a 23.4 Hz line on ay (sampled at 50 Hz) are found
    with their amplitudes; N stays within 4 sigma of the truth and no quantisation term appears."""
    rng = np.random.default_rng(78)
    n = 180_000
    a = white(rng, n, FS_HZ, N_TRUE, 3) + rate_random_walk(rng, n, FS_HZ, K_TRUE, 3)
    t = np.arange(n) / FS_HZ
    a[:, 0] += 0.05 * np.sin(2 * np.pi * 0.5 * t + 0.3)
    a[:, 1] += 0.03 * np.sin(2 * np.pi * 23.4 * t)
    path = _write(tmp_path, a, name="lines")
    assert main(["allan", str(path), "--json", "--whole"]) == 0
    out = json.loads(capsys.readouterr().out)
    found = {(ln["channel"], round(ln["frequency_hz"], 3)): ln["amplitude"] for ln in out["lines"]}
    assert set(found) == {("ax", 0.5), ("ay", 23.4)}, out["lines"]
    assert found[("ax", 0.5)] == pytest.approx(0.05, rel=0.1)
    assert found[("ay", 23.4)] == pytest.approx(0.03, rel=0.1)
    # left in, the 0.5 Hz line reads as N several times the truth, the 23.4 Hz one as Q at 5.6 sigma
    for ch in ("ax", "ay", "az"):
        terms = out["noise_terms"]["channels"][ch]
        assert terms["white_n"] == pytest.approx(N_TRUE, abs=4 * terms["white_n_sigma"]), ch
        assert terms["white_n"] == pytest.approx(N_TRUE, rel=0.1), ch
        assert terms["quantization_q"] <= 4 * terms["quantization_q_sigma"], ch
    assert main(["allan", str(path), "--whole"]) == 0
    text = capsys.readouterr().out
    assert "periodic lines" in text and "ax  0.5 Hz" in text and "ay  23.4 Hz" in text


def test_human_table_and_plot(
    static_record: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    png = tmp_path / "allan.png"
    assert main(["allan", str(static_record), "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "tau (s)" in text and "N white / velocity random walk" in text and "dwell" in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.stat().st_size > 20_000


def test_window_option_and_g_units(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A window in g: the Allan deviation comes out in m/s², 9.80665 times the g values."""
    rng = np.random.default_rng(3)
    a_g = white(rng, 20_000, FS_HZ, 1e-4, 3)
    path = _write(tmp_path, a_g, unit="g")
    assert main(["allan", str(path), "--json", "--window-s", "100", "300"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["adev_unit"] == "m/s2"
    assert out["window"]["start_s"] == pytest.approx(100.0) and out["window"]["end_s"] == pytest.approx(300.0)
    sel = a_g[(np.arange(20_000) / FS_HZ >= 100) & (np.arange(20_000) / FS_HZ <= 300)]
    expected_tau0 = np.sqrt(np.mean(np.diff(sel * 9.80665, axis=0) ** 2, axis=0) / 2)
    assert out["adev"]["ax"][0] == pytest.approx(expected_tau0[0], rel=1e-9)


def test_longest_segment_is_used(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = white(np.random.default_rng(4), 10_000, FS_HZ, 1e-3, 3)
    segs = (Segment(10.0, 40.0, "pos01"), Segment(50.0, 150.0, "pos02"), Segment(160.0, 190.0, "pos03"))
    path = _write(tmp_path, a, segments=segs)
    assert main(["allan", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert "pos02" in out["window"]["source"]
    assert out["window"]["n_samples"] == 5001


def _error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    return err


def test_missing_file_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["allan", str(tmp_path / "nope.csv")]) == 2
    assert "nope.csv" in _error_line(capsys)


def test_gap_in_time_stamps_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    n = 2000
    t = np.arange(n) / FS_HZ
    t[1000:] += 3.0
    path = _write(tmp_path, white(np.random.default_rng(5), n, FS_HZ, 1e-3, 3), t=t)
    assert main(["allan", str(path), "--whole"]) == 2
    err = _error_line(capsys)
    assert "gap of 3.02 s after t = 19.98 s" in err


def test_window_outside_recording_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, white(np.random.default_rng(6), 1000, FS_HZ, 1e-3, 3))
    assert main(["allan", str(path), "--window-s", "500", "600"]) == 2
    assert "holds 0 samples" in _error_line(capsys)
    assert main(["allan", str(path), "--window-s", "5", "1"]) == 2
    assert "START < END" in _error_line(capsys)


def test_too_short_stretch_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, white(np.random.default_rng(6), 40, FS_HZ, 1e-3, 3))
    assert main(["allan", str(path), "--whole"]) == 2
    assert "τ values" in _error_line(capsys)


def test_malformed_recording_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, white(np.random.default_rng(6), 100, FS_HZ, 1e-3, 3))
    lines = path.read_text().splitlines()
    lines[5] = lines[5].rsplit(",", 1)[0] + ",abc"
    path.write_text("\n".join(lines) + "\n")
    assert main(["allan", str(path)]) == 2
    assert path.name in _error_line(capsys)
