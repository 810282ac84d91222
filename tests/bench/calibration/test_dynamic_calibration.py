"""Dynamic calibration: injected truth recovered within the reported uncertainty."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bench.calibration import calibrate_recording
from bench.calibration.dynamic import DynamicCalibrationResult, calibrate_dynamic
from bench.calibration.kind import is_moving
from bench.recording import read_recording
from tests.support.dynamic_sim import DELAY_TRUE_S, EFFECTS, R_TRUE_M, TILT_TRUE_RAD, oscillation, rate, truth

RHO = np.array([[0.0, 0.004, -0.002], [0.003, 0.0, 0.001], [-0.002, 0.002, 0.0]])
Z_MAX = 3.0


def _z(est: object, sig: object, true: object) -> np.ndarray:
    return (np.asarray(est, dtype=float) - np.asarray(true, dtype=float)) / np.asarray(sig, dtype=float)


@pytest.fixture(scope="module")
def osc():  # type: ignore[no-untyped-def]
    run, rec = oscillation()
    res = calibrate_recording(rec)
    assert isinstance(res, DynamicCalibrationResult)
    return run, res


@pytest.fixture(scope="module")
def rate_pm():  # type: ignore[no-untyped-def]
    effects = {**EFFECTS, "proof_mass_offsets": {"rho_m": RHO.tolist()}}
    poses = ((90.0, 0.0), (0.0, 0.0), (90.0, 90.0), (80.0, 30.0), (10.0, 0.0), (80.0, 120.0))
    run, rec = rate(truth=truth(effects=effects), poses_deg=poses)
    return run, calibrate_recording(rec)


def test_oscillation_recovers_truth(osc) -> None:  # type: ignore[no-untyped-def]
    run, res = osc
    c = res.to_contract()
    assert c["procedure"] == "oscillation-2axis"
    assert {"lever_arm", "table_tilt", "time_skew"} <= set(c["terms"])
    # the truth has no proof-mass offsets: left out, and said why
    assert c["not_fitted"]["proof_mass_offsets"].startswith(("no evidence", "not determined"))
    assert c["model_selection"]["rule"] == "evidence"
    steps = {s["term"] for s in c["model_selection"]["steps"]}
    assert {"lever_arm", "table_tilt", "time_skew"} <= steps <= set(c["terms"][2:])
    assert np.all(np.abs(_z(c["bias"], c["bias_sigma"], run.bias_seen())) < Z_MAX)
    assert np.all(np.abs(_z(c["scale_matrix"], c["scale_matrix_sigma"], run.truth.K)) < Z_MAX)
    ex, es = c["extra"], c["extra_sigma"]
    assert np.all(np.abs(_z(ex["lever_arm"]["r_m"], es["lever_arm"]["r_m"], R_TRUE_M)) < Z_MAX)
    assert np.all(
        np.abs(_z(ex["table_tilt"]["tilt_rad"], es["table_tilt"]["tilt_rad"], TILT_TRUE_RAD)) < Z_MAX
    )
    assert abs(_z(ex["time_skew"]["delay_s"], es["time_skew"]["delay_s"], DELAY_TRUE_S)) < Z_MAX
    if "nonlinearity_quadratic" in ex:  # truth has none
        k2 = ex["nonlinearity_quadratic"]
        assert np.all(np.abs(_z(k2["k2_per_g"], es["nonlinearity_quadratic"]["k2_per_g"], 0.0)) < Z_MAX)
    # the paper's radius vector to ~1 mm
    assert np.max(np.abs(np.array(ex["lever_arm"]["r_m"]) - R_TRUE_M)) < 2e-3
    # the |g| check after: corrected, motion removed, |f| = g to the noise of 1-s blocks
    assert abs(c["g_check"]["after"]["mean_error_m_s2"]) < 2e-3
    json.dumps(c)


def test_oscillation_kalman_agrees_with_batch(osc) -> None:  # type: ignore[no-untyped-def]
    _, res = osc
    k = res.kalman
    assert k["agree"] and k["max_abs_z"] < 0.5
    # the filter's covariance is the white-noise bound: close to the batch sigma here
    assert 0.5 < k["filter_sigma_over_batch_sigma_median"] <= 1.05


def test_rate_table_lever_arm_and_proof_masses(rate_pm) -> None:  # type: ignore[no-untyped-def]
    run, res = rate_pm
    c = res.to_contract()
    ex, es = c["extra"], c["extra_sigma"]
    assert "proof_mass_offsets" in ex
    r = np.array(ex["lever_arm"]["r_m"])
    q = r + np.array(ex["proof_mass_offsets"]["rho_m"])
    q_true = R_TRUE_M + RHO
    # the rate-table paper: offsets to millimetres at ±200 °/s; here each proof mass to < 1 mm
    assert np.max(np.abs(q - q_true)) < 1e-3
    assert np.max(np.abs(r - q_true.mean(axis=0))) < 1e-3
    assert np.all(np.abs(_z(r, es["lever_arm"]["r_m"], q_true.mean(axis=0))) < Z_MAX)
    rho_true = q_true - q_true.mean(axis=0)
    assert np.all(
        np.abs(_z(ex["proof_mass_offsets"]["rho_m"], es["proof_mass_offsets"]["rho_m"], rho_true)) < Z_MAX
    )
    assert np.all(np.abs(_z(c["bias"], c["bias_sigma"], run.bias_seen())) < Z_MAX)
    assert np.all(np.abs(_z(c["scale_matrix"], c["scale_matrix_sigma"], run.truth.K)) < Z_MAX)
    assert res.kalman["agree"]


def test_rate_table_lever_arm_to_a_millimetre() -> None:
    """±200 °/s at the default three poses (the rate-table paper: offsets to mm at up to ±200 °/s)."""
    run, rec = rate(seed=4)
    c = calibrate_recording(rec).to_contract()
    r, rs = np.array(c["extra"]["lever_arm"]["r_m"]), np.array(c["extra_sigma"]["lever_arm"]["r_m"])
    assert np.max(np.abs(r - R_TRUE_M)) < 1e-3 and np.max(rs) < 1e-3
    assert np.all(np.abs(_z(r, rs, R_TRUE_M)) < Z_MAX)
    tilt = c["extra"]["table_tilt"]
    assert np.all(
        np.abs(_z(tilt["tilt_rad"], c["extra_sigma"]["table_tilt"]["tilt_rad"], TILT_TRUE_RAD)) < Z_MAX
    )
    assert np.all(np.abs(_z(c["bias"], c["bias_sigma"], run.bias_seen())) < Z_MAX)


def test_independent_example_rate_recording(independent_dir: Path) -> None:
    """An independent simulator's rate recording to ±240 °/s: its truth recovered."""
    stem = independent_dir / "example_rate_lever_known"
    rec = read_recording(stem.with_suffix(".csv"))
    truth_doc = json.loads(stem.with_name(stem.name + ".truth.json").read_text())
    c = calibrate_recording(rec).to_contract()
    assert np.all(np.abs(_z(c["bias"], c["bias_sigma"], truth_doc["bias_v"])) < Z_MAX)
    assert np.all(np.abs(_z(c["scale_matrix"], c["scale_matrix_sigma"], truth_doc["K_v_per_m_s2"])) < Z_MAX)
    # the sidecar already knows the lever arm and the data agree with it: nothing to fit
    assert c["terms"] == ["bias", "scale_matrix"] and c["extra"] == {}
    assert c["not_fitted"]["lever_arm"].startswith("no evidence")
    assert c["kalman_check"]["agree"]
    # declared, the lever arm is fitted and lands on the sidecar's value
    c = calibrate_dynamic(rec, terms=("lever_arm",)).to_contract()
    assert c["model_selection"]["rule"] == "declared" and c["terms"] == ["bias", "scale_matrix", "lever_arm"]
    r = np.array(c["extra"]["lever_arm"]["r_m"])
    assert np.max(np.abs(r - [0.06, 0.0, -0.015])) < 1e-3
    assert np.all(np.abs(_z(r, c["extra_sigma"]["lever_arm"]["r_m"], [0.06, 0.0, -0.015])) < Z_MAX)
    assert c["kalman_check"]["agree"]


def test_unmodelled_lever_arm_is_biased_and_fitted_one_is_not() -> None:
    """Ignoring the lever arm (the believed zero) leaves its centripetal terms in the residuals."""
    run, rec = oscillation(duration_s=30.0)
    bad = calibrate_dynamic(rec, terms=(), cross_check=False)
    good = calibrate_dynamic(rec, terms=("lever_arm", "table_tilt", "time_skew"), cross_check=False)
    z_good = np.abs(_z(good.K, good.K_sigma, run.truth.K)).max()
    assert bad.residual_rms > 1.3 * good.residual_rms  # 0.46 mV (0.026 m/s²) of centripetal signal unmodelled
    assert z_good < Z_MAX


def test_dispatch_and_bad_input() -> None:
    _, rec = oscillation(duration_s=30.0)
    assert is_moving(rec)
    assert not is_moving(replace(rec, sidecar=replace(rec.sidecar, procedure="static-12")))
    # no procedure, or another bench's name for it, but a segment in which the table turns
    assert is_moving(replace(rec, sidecar=replace(rec.sidecar, procedure=None)))
    assert is_moving(replace(rec, sidecar=replace(rec.sidecar, procedure="tumble-b7 (lab 2)")))
    # a rate-1axis recording at one pose turning about the vertical only: K cannot be determined
    _, flat = rate(rates_deg_s=(50.0, 100.0), poses_deg=((0.0, 0.0),), dwell_s=3.0)
    with pytest.raises(ValueError, match=r"cannot be determined|cannot determine"):
        calibrate_recording(flat)
    nan = rec.accel_raw.copy()
    nan[100, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        calibrate_dynamic(replace(rec, accel_raw=nan), terms=("lever_arm",))
    with pytest.raises(ValueError, match=r"sample 100 \(t = 1 s\): y channel is not finite"):
        calibrate_recording(replace(rec, accel_raw=nan))
    with pytest.raises(ValueError, match="table"):
        calibrate_dynamic(replace(rec, table_deg=None))


def test_daq_gaps_are_bridged() -> None:
    """Dropped DAQ blocks: derivatives per stretch between gaps, a too-short stretch left out."""
    run, rec = oscillation(duration_s=60.0)
    keep = np.ones(rec.n_samples, dtype=bool)
    keep[3000:3400] = False  # a 4-s gap while both axes move
    keep[5000:5010] = False
    keep[5013:5020] = False  # leaves a 3-sample stretch, shorter than the derivative window
    cut = replace(rec, t_s=rec.t_s[keep], accel_raw=rec.accel_raw[keep], table_deg=rec.table_deg[keep],
                  temp_c=rec.temp_c[keep])  # fmt: skip
    res = calibrate_recording(cut)
    assert isinstance(res, DynamicCalibrationResult) and res.fit is not None
    assert res.fit.n_used < int(keep.sum()) - 3
    c = res.to_contract()
    assert np.all(np.abs(_z(c["scale_matrix"], c["scale_matrix_sigma"], run.truth.K)) < Z_MAX)
    assert np.all(
        np.abs(_z(c["extra"]["lever_arm"]["r_m"], c["extra_sigma"]["lever_arm"]["r_m"], R_TRUE_M)) < Z_MAX
    )


def test_reported_sigma_is_honest_over_seeds() -> None:
    """Over independent runs the z-scores of every parameter behave like N(0, 1) or better."""
    zs = []
    for seed in range(10):
        run, rec = oscillation(seed=10 + seed, duration_s=60.0, truth=truth(seed=seed))
        res = calibrate_dynamic(rec, terms=("lever_arm", "table_tilt", "time_skew"), cross_check=False)
        th_true = np.concatenate(
            [run.bias_seen(), run.truth.K.ravel(), R_TRUE_M, TILT_TRUE_RAD, [DELAY_TRUE_S]]
        )
        assert res.fit is not None
        zs.append((res.fit.theta - th_true) / res.fit.sigma)
    z = np.abs(np.concatenate(zs))
    assert z.max() < 4.5
    assert np.mean(z < 2.0) > 0.88  # N(0, 1): 0.954
    assert np.sqrt(np.mean(z**2)) < 1.3


def test_cli_json_contract_for_a_dynamic_recording(
    independent_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from api.cli import main

    example = independent_dir / "example_rate_lever_known.csv"
    assert main(["calibrate", str(example), "--json", "--terms", "lever_arm"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in (
        "unit",
        "channel_unit",
        "procedure",
        "bias",
        "bias_sigma",
        "scale_matrix",
        "scale_matrix_sigma",
        "terms",
        "extra",
        "residual_rms",
        "g_check",
    ):
        assert key in out
    assert out["procedure"] == "rate-1axis" and out["terms"][:3] == ["bias", "scale_matrix", "lever_arm"]
    assert set(out["extra"]) == set(out["terms"][2:])
    assert np.shape(out["extra"]["lever_arm"]["r_m"]) == (3,)
    assert out["model_selection"]["rule"] == "declared"
    assert main(["calibrate", str(example), "--terms", "lever_arm"]) == 0
    text = capsys.readouterr().out
    assert "lever_arm.r_m" in text and "chosen by declared" in text
    assert main(["calibrate", str(example), "--terms", "lever"]) == 2
    assert "--terms 'lever'" in capsys.readouterr().err


def test_clean_recording_is_calibrated_with_the_first_order_model() -> None:
    """A clean oscillation (no lever arm beyond the believed one, level table, no skew): the
    evidence supports no extra term, so the fit is the first-order one, with its sigmas;
    fitting every term the motion determines would spread the same data over more
    parameters (the z-bias sigma grows several-fold) for nothing."""
    from bench.calibration.dynamic import choose_spec
    from bench.estimation.motion_data import prepare_motion

    run, rec = oscillation(seed=5, truth=truth(effects={}))
    res = calibrate_dynamic(rec, cross_check=False)
    c = res.to_contract()
    assert c["terms"] == ["bias", "scale_matrix"] and c["model_selection"]["steps"] == []
    assert all(
        why.startswith(("no evidence", "not determined", "tried only")) for why in c["not_fitted"].values()
    )
    first = calibrate_dynamic(rec, terms=(), cross_check=False)
    np.testing.assert_allclose(res.bias_sigma, first.bias_sigma, rtol=1e-12)
    assert np.all(np.abs(_z(res.bias, res.bias_sigma, run.bias_seen())) < Z_MAX)
    geo = rec.sidecar.table
    assert geo is not None
    q = rec.table_rad_unwrapped()
    m = prepare_motion(rec.t_s, q, geo.axis_vectors, geo.mount_matrix)
    spec, _ = choose_spec(
        m, rec.accel_raw, rec.sidecar.g_local_m_s2, np.asarray(geo.lever_arm_m, dtype=float)
    )
    everything = calibrate_dynamic(rec, terms=spec.terms, cross_check=False)
    assert len(spec.terms) >= 3
    assert everything.bias_sigma[2] > 2.0 * res.bias_sigma[2]


@pytest.mark.slow
def test_evidence_selected_model_is_honest_on_clean_runs() -> None:
    """Clean oscillations (no effect beyond the believed geometry): the evidence rule adds a
    term in at most one run of eight (false alarm 0.01 per step), and bias and K z-scores
    against the concealed truth behave like N(0, 1)."""
    zs, extra_terms = [], 0
    for seed in range(8):
        run, rec = oscillation(seed=40 + seed, duration_s=60.0, truth=truth(seed=seed, effects={}))
        res = calibrate_dynamic(rec, cross_check=False)
        extra_terms += len(res.extra) > 0
        zs.append(_z(np.r_[res.bias, res.K.ravel()], np.r_[res.bias_sigma, res.K_sigma.ravel()],
                     np.r_[run.bias_seen(), run.truth.K.ravel()]))  # fmt: skip
    z = np.abs(np.concatenate(zs))
    assert extra_terms <= 1
    assert z.max() < 4.5 and np.sqrt(np.mean(z**2)) < 1.3 and np.mean(z < 2.0) > 0.88
