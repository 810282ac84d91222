"""``calibrate`` on a moving recording fits only the catalogue terms its diagnosis claims,
including where the bench families' head to head withdraws the catalogue's claims."""

from __future__ import annotations

from dataclasses import replace

import pytest

from api.simulated_recording import to_recording
from bench.calibration.diagnose import diagnose_recording
from bench.calibration.dynamic import calibrate_dynamic
from bench.diagnosis import Diagnosis
from bench.diagnosis.moving_report import PARAM
from bench.recording import Recording
from drivers.sim.offline import DEFAULT_AXES, simulate_oscillation
from drivers.sim.physics import SensorPhysics, SensorTruth
from tests.support.diagnose_dynamic_cases import DYNAMIC_CASES, moving_recording
from tests.support.families_cases import cases

HEAD_TO_HEAD = (
    "clock_drift: 100 ppm, rate",
    "angle_harmonic: inner axis, once per turn, ax, oscillation, 1.0 mg",
)
"""Families the catalogue imitates on their motion (docs/diagnose.md, "Head to head of the bench
families"): a growing delay taken as nonlinearity_quadratic, a once-per-turn harmonic as table_tilt."""


def _claimed_and_fitted(rec: Recording) -> tuple[Diagnosis, set[str], set[str], dict[str, str]]:
    """The diagnosis, the dynamic-model terms it claims, the terms calibrate fits and why
    calibrate left the others out."""
    d = diagnose_recording(rec)
    cal = calibrate_dynamic(rec, cross_check=False)
    claimed = {f.effect for f in d.findings if f.effect in PARAM}
    return d, claimed, set(cal.terms) - {"bias", "scale_matrix"}, cal.not_fitted


@pytest.mark.slow
def test_calibrate_leaves_out_the_steps_the_diagnosis_replaced() -> None:
    """ax delayed 5 ms behind ay, az: the catalogue's greedy path takes a common time skew
    (with a lever arm and proof masses for what it leaves), which the diagnosis replaces by
    ḟ_x on ax (``test_one_channel_delay_is_discovered_as_fdot_on_its_channel``); calibrate
    must not fit the replaced terms."""
    seed = 7
    clean = moving_recording({}, seed)
    raw = clean.accel_raw.copy()
    raw[:, 0] = moving_recording({"time_skew": {"delay_s": 0.005}}, seed).accel_raw[:, 0]
    rec = replace(clean, accel_raw=raw)
    d = diagnose_recording(rec)
    cal = calibrate_dynamic(rec, cross_check=False)
    claimed = {f.effect for f in d.findings}
    fitted = set(cal.terms) - {"bias", "scale_matrix"}
    assert fitted <= claimed, (fitted, claimed)
    assert d.discovered  # the replacement happened: the test is about it


@pytest.mark.slow
@pytest.mark.parametrize("effect", ["lever_arm", "nonlinearity_quadratic"])
def test_calibrate_fits_what_the_diagnosis_claims(effect: str) -> None:
    case = DYNAMIC_CASES[effect]
    rec = case.recording(5 * case.limit, 101)
    claimed = {f.effect for f in diagnose_recording(rec).findings}
    fitted = set(calibrate_dynamic(rec, cross_check=False).terms) - {"bias", "scale_matrix"}
    assert fitted == claimed == {effect}


@pytest.mark.slow
@pytest.mark.parametrize("name", HEAD_TO_HEAD)
def test_calibrate_fits_exactly_what_the_diagnosis_claims_after_the_head_to_head(name: str) -> None:
    (case,) = [c for c in cases() if c.name == name]
    withdrawn = 0
    for seed in (100, 101, 102):
        d, claimed, fitted, why = _claimed_and_fitted(case.recording(seed))
        assert fitted == claimed, (seed, fitted, claimed)
        if any("are withdrawn" in n for n in d.notes):
            withdrawn += 1
            assert any("head to head" in w for w in why.values()), why
    assert withdrawn >= 1  # the head to head withdrew a claim: the test is about it


def _short_harmonic(seed: int) -> Recording:
    """30 s of the oscillation at 50 Hz with a 2 mg once-per-turn disturbance of the inner
    axis on ax (``angle_harmonic``, phase 0.4 rad): the catalogue takes it for table_tilt."""
    amp = [2e-3 * 9.80665, 0.0, 0.0]
    eff = {"angle_harmonic": {"axis": 3, "harmonic": 1, "amplitude_m_s2": amp, "phase_rad": 0.4}}
    truth = SensorTruth.typical("V", seed=seed).with_effects(eff)
    run = simulate_oscillation(SensorPhysics(truth, DEFAULT_AXES, seed=seed), 50.0, duration_s=30.0)
    return to_recording(run, serial=f"SIM-DYN-{seed}")


@pytest.mark.slow  # 15-35 s: a moving diagnosis and calibration with the family search
def test_calibrate_leaves_out_a_claim_the_head_to_head_withdraws() -> None:
    d, claimed, fitted, why = _claimed_and_fitted(_short_harmonic(1))
    assert any(f.effect == "angle_harmonic" for f in d.findings)
    assert any("are withdrawn" in n for n in d.notes)
    assert fitted == claimed and "table_tilt" not in fitted
    # the catalogue claimed table_tilt for the harmonic and the head to head withdrew it
    assert "head to head" in why["table_tilt"]
