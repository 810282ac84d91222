"""Motion effects concealed in simulated moving-table recordings (truth: drivers/sim/physics.py).

Scenarios and limits: ``benchmarks/diagnose_dynamic_cases.py`` (docs/diagnose.md). At 10x
its limit each effect is found and its parameter recovered within 3 of its own sigmas (lever
arm, delay, low-pass and quadratic nonlinearity on the 90 s oscillation; proof-mass offsets,
beside a 12 mm lever arm, on the rate run with tilted poses); a concealed low-pass is
reported as a delay of its time constant, named as confounded with ``sensor_lowpass``. At
3x the proof masses and the nonlinearity are found on two further seeds. Clean
oscillation and rate runs report nothing, neither a catalogue effect nor a library term.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.calibration.diagnose import diagnose_recording
from tests.support.diagnose_dynamic_cases import (
    DYNAMIC_CASES,
    LEVER_FOR_PROOF_MASS_M,
    dynamic_z,
    moving_recording,
)


@pytest.mark.parametrize(
    "effect",
    [
        "lever_arm",
        "time_skew",
        "sensor_lowpass",
        "nonlinearity_quadratic",
        pytest.param("proof_mass_offsets", marks=pytest.mark.slow),
    ],
)
def test_motion_effect_at_ten_times_its_limit_is_found_and_measured(effect: str) -> None:
    case = DYNAMIC_CASES[effect]
    size = 10 * case.limit
    d = diagnose_recording(case.recording(size, seed=11))
    assert d.method == "dynamic"
    expected = ["lever_arm", case.finding] if case.extra else [case.finding]
    assert [f.effect for f in d.findings] == expected, [f.summary for f in d.findings]
    z = dynamic_z(case, d, size)
    assert z is not None and z < 3.0, z
    if effect == "sensor_lowpass":
        assert d.findings[0].confounded_with == ("sensor_lowpass",)
    if effect == "proof_mass_offsets":
        lever = next(f for f in d.findings if f.effect == "lever_arm")
        r, s = np.array(lever.parameters["r_m"]), np.array(lever.sigma["r_m"])
        assert np.all(np.abs(r - np.array(LEVER_FOR_PROOF_MASS_M)) < 3 * s)


@pytest.mark.slow
@pytest.mark.parametrize("effect", ["nonlinearity_quadratic", "proof_mass_offsets"])
def test_motion_effect_at_three_times_its_limit_is_found(effect: str) -> None:
    case = DYNAMIC_CASES[effect]
    size = 3 * case.limit
    for seed in (21, 22):
        d = diagnose_recording(case.recording(size, seed))
        z = dynamic_z(case, d, size)
        assert z is not None, (seed, [f.summary for f in d.findings])
        assert z < 4.0, (seed, z)


@pytest.mark.slow
def test_rate_table_lever_arm_at_ten_times_the_oscillation_limit() -> None:
    case = DYNAMIC_CASES["lever_arm"]
    d = diagnose_recording(moving_recording(case.effects(10 * case.limit), seed=12, kind="rate"))
    assert [f.effect for f in d.findings] == ["lever_arm"]
    z = dynamic_z(case, d, 10 * case.limit)
    assert z is not None and z < 3.0
    assert d.baseline.chi2_dof > 1.5 and d.final.chi2_dof < 1.1
    assert "omega^2" in d.correlates_with()


@pytest.mark.parametrize("kind", ["oscillation", "rate"])
def test_clean_moving_recordings_report_nothing(kind: str) -> None:
    d = diagnose_recording(moving_recording({}, seed=13, kind=kind))
    assert d.findings == () and d.discovered == () and d.where == "nowhere beyond the noise"
    assert 0.8 < d.final.chi2_dof < 1.2
