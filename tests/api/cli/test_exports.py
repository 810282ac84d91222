"""Exports of the fitted model, each loaded back with the other tool's own reader: imucal's
``CalibrationInfo.from_json``, PyYAML for the Kalibr YAML, gcc for the C header; the CLI on the
shipped example recording."""

from __future__ import annotations

import datetime as dt
import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from api.cli import main
from api.exports import certified_uncertainty, export_text, kalibr_noise
from bench.estimation.allan import overlapping_allan
from bench.export import FORMATS, to_c_header, to_imucal, to_json, to_kalibr
from tests.conftest import STATIC_EXAMPLE, copy_example
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
    for key in ("accelerometer_noise_density", "accelerometer_random_walk", "update_rate", "time_offset"):
        assert isinstance(doc[key], float), key
    # no gyroscope was measured: its noise is left out (unknown), never stated as a perfect 0
    assert "gyroscope_noise_density" not in doc and "gyroscope_random_walk" not in doc
    assert "No gyroscope was measured" in text
    assert doc["rostopic"] == "/imu0" and doc["accelerometer_noise_density"] == 3.1e-3
    assert doc["update_rate"] == 1000.0
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
    assert rate == fs
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


def test_cli_writes_each_format_from_a_recording(tmp_path: Path) -> None:
    imucal = pytest.importorskip("imucal")
    rec = copy_example(STATIC_EXAMPLE, tmp_path)
    assert main(["calibrate", str(rec), "--json"]) == 0
    for fmt in ("imucal", "kalibr", "c-header", "json"):
        out = tmp_path / f"out.{fmt}"
        assert main(["export", str(rec), "--format", fmt, "--out", str(out)]) == 0
        assert out.stat().st_size > 200
    info = imucal.CalibrationInfo.from_json((tmp_path / "out.imucal").read_text())
    assert info.K_a.shape == (3, 3)
    kal = yaml.safe_load((tmp_path / "out.kalibr").read_text())["imu0"]
    assert kal["accelerometer_noise_density"] > 0 and kal["update_rate"] == 10.0  # the sidecar's rate
    assert main(["export", str(tmp_path / "missing.csv"), "--format", "json"]) == 2


def test_kalibr_update_rate_is_the_recordings_nominal_rate_not_its_time_stamps_quotient() -> None:
    # a 100 Hz stretch from 101.13 s in floating point: (n - 1) / span is 99.99999999999999
    t = 101.13 + np.arange(4500) * 0.01
    taus = [0.01, 0.1, 1.0]
    adev = [[1e-4, 3e-5, 1e-5]] * 3
    series = {
        "taus_s": taus,
        "adev": adev,
        "start_s": float(t[0]),
        "end_s": float(t[-1]),
        "n_samples": t.size,
    }
    assert (t.size - 1) / (t[-1] - t[0]) != 100.0  # the quotient the YAML used to carry
    assert kalibr_noise(series, FIT)[0] == 100.0  # rounded to six significant digits
    assert kalibr_noise({**series, "sample_rate_hz": 99.5}, FIT)[0] == 99.5  # the sidecar's rate


CERT = {
    "results": {
        "bias": {
            "value": B.tolist(),
            "expanded_uncertainty": [2.1e-5, 2.2e-5, 2.3e-5],
            "unit": "V",
            "k": 2.0,
        },
        "scale_matrix": {
            "value": K.tolist(),
            "expanded_uncertainty": (np.full((3, 3), 4.4e-6) + np.eye(3) * 1e-6).tolist(),
            "unit": "V/(m/s2)",
            "k": 2.05,
        },
    }
}
ISSUED = dt.datetime(2026, 11, 20, 9, 30, tzinfo=dt.UTC)


def test_every_export_of_a_certified_run_carries_number_date_and_uncertainties() -> None:
    u = certified_uncertainty("CB-2026-00042", ISSUED, CERT)
    series = {"taus_s": [0.01, 0.1], "adev": [[1e-4, 3e-5]] * 3, "start_s": 0.0, "end_s": 60.0,
              "n_samples": 6001, "sample_rate_hz": 100.0}  # fmt: skip
    texts = {fmt: export_text(fmt, FIT, series, "run r1", u) for fmt in FORMATS}
    for fmt, text in texts.items():
        assert "CB-2026-00042" in text and "2026-11-20" in text, fmt
        assert "2.1e-05" in text and "2.05" in text, fmt  # U of b_x and the k of K
    doc = json.loads(texts["json"])["uncertainty"]
    assert doc["certificate"] == {"number": "CB-2026-00042", "issued_on": "2026-11-20"}
    assert doc["bias"] == {"uncertainty": [2.1e-5, 2.2e-5, 2.3e-5], "k": 2.0, "unit": "V"}
    assert doc["scale_matrix"]["uncertainty"] == CERT["results"]["scale_matrix"]["expanded_uncertainty"]
    cert = yaml.safe_load(texts["kalibr"])["imu0"]["calbench_certificate"]
    assert cert["number"] == "CB-2026-00042" and cert["issued_on"] == "2026-11-20"
    assert cert["bias_uncertainty"] == [2.1e-5, 2.2e-5, 2.3e-5] and cert["scale_matrix_k"] == 2.05
    assert '#define CALBENCH_CERTIFICATE "CB-2026-00042"' in texts["c-header"]
    imucal = pytest.importorskip("imucal")
    info = imucal.CalibrationInfo.from_json(texts["imucal"])  # still loads in imucal
    assert "certificate CB-2026-00042, issued 2026-11-20" in info.comment
    with pytest.raises(ValueError, match="certificate CB-1: its results hold no readable uncertainties"):
        certified_uncertainty("CB-1", ISSUED, {"results": {}})


def test_an_uncertified_export_states_the_fits_own_sigma_and_says_it_is_not_certified() -> None:
    fit = stored_fit(bias_sigma=[1e-5, 2e-5, 3e-5], scale_matrix=K.tolist())
    doc = json.loads(to_json(fit))["uncertainty"]
    assert doc["certificate"] is None and doc["bias"]["k"] == 1.0
    assert doc["bias"]["uncertainty"] == [1e-5, 2e-5, 3e-5] and "not a certified calibration" in doc["basis"]
    kal = yaml.safe_load(to_kalibr(fit, sample_rate_hz=100.0, noise_density_m_s2_sqrt_hz=1e-3,
                                   random_walk_m_s3_sqrt_hz=1e-4))  # fmt: skip
    assert kal["imu0"]["calbench_certificate"]["number"] is None
    assert '#define CALBENCH_CERTIFICATE ""' in to_c_header(fit)
