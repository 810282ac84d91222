"""Simulated recordings: the file round trip, the CLI, and calibration back to the injected truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from api.cli import main
from api.simulated_recording import nominal_geometry, to_recording, truth_path_for, write_simulated
from bench.recording import read_recording
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth

calibration = pytest.importorskip(
    "bench.calibration", reason="bench.calibration (calibrate_recording) not present"
)

G = 9.81535


def _run(unit_seed: int, noise_seed: int, dwell_s: float = 30.0):
    truth = SensorTruth.typical("V", seed=unit_seed)
    physics = SensorPhysics(truth, DEFAULT_AXES, None, G, seed=noise_seed, encoder_resolution_deg=1e-4)
    return simulate_static(static12_poses_deg(), dwell_s, physics, 100.0)


def _z_scores(result, run) -> np.ndarray:
    """(12,) (estimate − truth)/σ for bias and K; the truth bias is the one the run's windows saw."""
    zb = (result.bias - run.bias_seen()) / result.bias_sigma
    zk = (result.K - run.truth.K) / result.K_sigma
    return np.concatenate([zb, zk.ravel()])


def test_written_recording_reads_back_and_keeps_the_truth_apart(tmp_path):
    run = _run(1, 2, dwell_s=3.0)
    path = tmp_path / "sim.csv"
    geometry = nominal_geometry(run, (0.01, 0.0, 0.0))
    write_simulated(path, run, serial="SN-T1", geometry=geometry, seed=2)
    rec = read_recording(path)
    assert rec.sidecar.unit_serial == "SN-T1"
    assert rec.sidecar.channel_unit == "V"
    assert rec.sidecar.procedure == "static-12"
    assert rec.sidecar.table is not None and rec.sidecar.table.lever_arm_m == (0.01, 0.0, 0.0)
    assert rec.sidecar.table.encoder_resolution_deg == 1e-4  # the encoders' step travels in the sidecar
    assert [s.label for s in rec.sidecar.segments or ()] == [s[2] for s in run.segments]
    np.testing.assert_allclose(rec.accel_raw, run.raw, rtol=1e-12)
    np.testing.assert_allclose(rec.table_deg, run.encoder_deg, atol=1e-9)
    doc = json.loads(truth_path_for(path).read_text())
    np.testing.assert_allclose(doc["scale_matrix"], run.truth.K)
    np.testing.assert_allclose(doc["bias_run"], run.bias_seen())
    assert "bias" not in json.loads(path.with_suffix(".json").read_text())  # the sidecar holds no truth


def test_sidecar_declares_the_step_the_encoders_read_in():
    """The physics' encoder step, ``encoder_hold``'s where it holds poses, none for exact readings."""
    truth = SensorTruth.typical("V", seed=1)
    for physics, step in (
        (SensorPhysics(truth, DEFAULT_AXES, None, G, seed=2), None),
        (SensorPhysics(truth, DEFAULT_AXES, None, G, seed=2, encoder_resolution_deg=1e-3), 1e-3),
        (
            SensorPhysics(
                truth.with_effects({"encoder_hold": {"step_deg": 2e-4}}), DEFAULT_AXES, None, G, seed=2
            ),
            2e-4,
        ),
    ):
        run = simulate_static(static12_poses_deg(), 1.0, physics, 100.0)
        table = to_recording(run, serial="x").sidecar.table
        assert table is not None and table.encoder_resolution_deg == step
        if step:  # the readings lie on the declared grid
            np.testing.assert_allclose(run.encoder_deg / step, np.round(run.encoder_deg / step), atol=1e-6)


def test_geometry_must_match_the_encoders():
    run = _run(1, 2, dwell_s=1.0)
    geo = nominal_geometry(run)
    bad = type(geo)(axes=geo.axes[:2])
    with pytest.raises(ValueError, match="2 table axes, the run recorded 3 encoders"):
        to_recording(run, serial="x", geometry=bad)


def test_static_recording_calibrates_back_within_its_uncertainty(tmp_path):
    run = _run(7, 70)
    path = tmp_path / "static.csv"
    write_simulated(path, run, serial="SN-CAL")
    result = calibration.calibrate_recording(read_recording(path))
    z = _z_scores(result, run)
    assert np.max(np.abs(z)) < 4.0, z
    # the sigmas are not inflated either: bias within a few µg-equivalents, scale within 1e-4
    assert np.max(np.abs(result.bias - run.bias_seen()) / np.diag(run.truth.K)) < 5e-4
    np.testing.assert_allclose(result.K, run.truth.K, atol=2e-4 * run.truth.K[0, 0])


@pytest.mark.slow
def test_reported_uncertainty_is_honest_over_many_runs():
    """Over 20 units and noise seeds the z-scores of all 12 parameters have unit scatter."""
    zs = np.array(
        [
            _z_scores(calibration.calibrate_recording(to_recording(r, serial="x")), r)
            for r in (_run(seed, 100 + seed) for seed in range(20))
        ]
    )
    rms = np.sqrt(np.mean(zs**2))
    # 240 z-scores: RMS within ±20 % of 1 when the sigmas are honest
    assert 0.8 < rms < 1.2, rms
    assert np.mean(np.abs(zs) > 3.0) < 0.02


def test_cli_writes_a_recording_with_the_effect_in_the_truth(tmp_path, capsys):
    out = tmp_path / "cli.csv"
    code = main(
        [
            "simulate",
            "--procedure",
            "static-12",
            "--dwell-s",
            "2",
            "--effect",
            "nonlinearity_quadratic:k2_per_g=0,0,1.5e-3",
            "--effect",
            "table_tilt:tilt_rad=1e-3,-2e-3",
            "--seed",
            "5",
            "-o",
            str(out),
        ]
    )
    assert code == 0
    doc = json.loads(truth_path_for(out).read_text())
    assert doc["effects"] == {
        "nonlinearity_quadratic": {"k2_per_g": [0.0, 0.0, 1.5e-3]},
        "table_tilt": {"tilt_rad": [1e-3, -2e-3]},
    }
    assert read_recording(out).n_samples > 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--effect", "lever_arm:r_m=1,2"], "expected 3 values, got 2"),
        (["--effect", "lever_arm:rho=1,2,3"], "no parameter 'rho'"),
        (["--effect", "gravity_wave:x=1"], "unknown effect"),
        (["--effect", "time_skew:delay_s=nan"], "finite"),
        (["--noise", "loudness=3"], "KEY=VALUE"),
        (["--effect", "pose_error:angles_rad=0,0"], "1 angle pairs given, the run has 12 windows"),
    ],
)
def test_cli_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    code = main(["simulate", "--dwell-s", "1", *args, "-o", str(tmp_path / "x.csv")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert message in err and "\n" not in err
