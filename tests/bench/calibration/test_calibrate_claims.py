"""``calibrate`` on a moving recording fits only the catalogue terms its diagnosis claims."""

from __future__ import annotations

from dataclasses import replace

import pytest

from bench.calibration.diagnose import diagnose_recording
from bench.calibration.dynamic import calibrate_dynamic
from tests.support.diagnose_dynamic_cases import DYNAMIC_CASES, moving_recording


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
