"""Exports of the fitted model, each loaded back with the other tool's own reader: imucal's
``CalibrationInfo.from_json``, PyYAML for the Kalibr YAML, gcc for the C header; the CLI on the
shared example recording."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from api.cli import main
from api.exports import kalibr_noise
from bench.estimation.allan import overlapping_allan
from bench.export import to_c_header, to_imucal, to_json, to_kalibr
from tests.support.fits import stored_fit

RNG = np.random.default_rng(14)
B = np.array([1.504, 1.497, 1.502])
K = np.array([[0.01744, 9.2e-5, -1.08e-4], [1e-5, 0.0175, 2e-5], [3e-5, -2e-5, 0.0176]])
FIT = stored_fit(unit="SN-EX/1", channel_unit="V", bias=B.tolist(), scale_matrix=K.tolist())
F = RNG.normal(0.0, 9.8, size=(20, 3))  # specific forces (m/s2)
RAW = B + F @ K.T  # raw = b + K f


def test_imucal_loads_the_json_and_recovers_the_specific_force() -> None:
    imucal = pytest.importorskip("imucal")
    info = imucal.CalibrationInfo.from_json(to_imucal(FIT, "run r1"))
    assert type(info).__name__ == "FerrarisCalibrationInfo" and info.from_acc_unit == "V"
    acc, gyr = info.calibrate(RAW, np.zeros_like(RAW), acc_unit="V", gyr_unit="deg/s")
    assert np.allclose(acc, F, rtol=0, atol=1e-9)
    assert np.allclose(gyr, 0.0) and "no gyroscope was calibrated" in info.comment


def test_kalibr_yaml_has_kalibrs_keys_and_the_correction_recovers_f() -> None:
    text = to_kalibr(FIT, sample_rate_hz=1000.0, noise_density_m_s2_sqrt_hz=3.1e-3,
                     random_walk_m_s3_sqrt_hz=2e-4, source="run r1")  # fmt: skip
    doc = yaml.safe_load(text)["imu0"]
    for key in ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
                "gyroscope_random_walk", "update_rate", "time_offset"):  # fmt: skip
        assert isinstance(doc[key], float), key
    assert doc["rostopic"] == "/imu0" and doc["accelerometer_noise_density"] == 3.1e-3
    assert np.asarray(doc["T_i_b"]).shape == (4, 4)
    corr = doc["calbench_correction"]
    f = (np.asarray(corr["correction_matrix"]) @ (RAW - np.asarray(corr["bias"])).T).T
    assert np.allclose(f, F, rtol=0, atol=1e-9) and corr["channel_unit"] == "V"
    with pytest.raises(ValueError, match="noise density must be a finite number"):
        to_kalibr(FIT, sample_rate_hz=1e3, noise_density_m_s2_sqrt_hz=math.nan, random_walk_m_s3_sqrt_hz=0)


def test_kalibr_noise_density_of_white_noise_is_sigma_over_root_rate() -> None:
    fs, sigma_v = 500.0, 2e-4  # white noise of 0.2 mV per sample
    x = RNG.normal(0.0, sigma_v, size=(60_000, 3))
    res = overlapping_allan(x, fs)
    allan = {"taus_s": res.taus_s.tolist(), "adev": res.adev.T.tolist(), "start_s": 0.0,
             "end_s": (x.shape[0] - 1) / fs, "n_samples": x.shape[0]}  # fmt: skip
    rate, density, walk = kalibr_noise(allan, FIT)
    expected = sigma_v / math.sqrt(fs) / K[0, 0]  # the largest of the channels: smallest K_ii
    assert rate == pytest.approx(fs)
    assert density == pytest.approx(expected, rel=0.05)
    assert walk > 0


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
def test_c_header_compiles_and_corrects_like_numpy(tmp_path: Path) -> None:
    (tmp_path / "cal.h").write_text(to_c_header(FIT, "run r1"))
    rows = "\n".join("{" + ", ".join(f"{v:.17g}" for v in r) + "}," for r in RAW)
    (tmp_path / "main.c").write_text(
        '#include <stdio.h>\n#include "cal.h"\n'
        f"static const double RAW[{len(RAW)}][3] = {{\n{rows}\n}};\n"
        "int main(void) { double f[3]; int k;\n"
        f"  for (k = 0; k < {len(RAW)}; ++k) {{ calbench_correct(RAW[k], f); "
        'printf("%.17g %.17g %.17g\\n", f[0], f[1], f[2]); }\n  return 0; }\n'
    )
    exe = tmp_path / "cal"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Werror", "-o", str(exe), str(tmp_path / "main.c")],
                   check=True, capture_output=True)  # fmt: skip
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    got = np.array([[float(v) for v in line.split()] for line in out.splitlines()])
    assert np.allclose(got, F, rtol=0, atol=1e-9)
    assert "CALBENCH_CAL_SN_EX_1_H" in (tmp_path / "cal.h").read_text()


def test_plain_json_and_a_singular_model_is_refused() -> None:
    doc = json.loads(to_json(FIT))
    assert doc["format"] == "calbench-correction/1"
    assert np.allclose(np.asarray(doc["correction_matrix"]) @ K, np.eye(3), atol=1e-12)
    with pytest.raises(ValueError, match="singular"):
        to_json(stored_fit(scale_matrix=[[1, 0, 0], [1, 0, 0], [0, 0, 1]]))


def test_cli_writes_each_format_from_a_recording(shared_dir: Path, tmp_path: Path) -> None:
    imucal = pytest.importorskip("imucal")
    src = shared_dir / "data" / "examples"
    for ext in ("csv", "json"):
        shutil.copy(src / f"example_static12.{ext}", tmp_path / f"rec.{ext}")
    rec = tmp_path / "rec.csv"
    assert main(["calibrate", str(rec), "--json"]) == 0
    for fmt in ("imucal", "kalibr", "c-header", "json"):
        out = tmp_path / f"out.{fmt}"
        assert main(["export", str(rec), "--format", fmt, "--out", str(out)]) == 0
        assert out.stat().st_size > 200
    info = imucal.CalibrationInfo.from_json((tmp_path / "out.imucal").read_text())
    assert info.K_a.shape == (3, 3)
    kal = yaml.safe_load((tmp_path / "out.kalibr").read_text())["imu0"]
    assert kal["accelerometer_noise_density"] > 0 and kal["update_rate"] > 0
    assert main(["export", str(tmp_path / "missing.csv"), "--format", "json"]) == 2
