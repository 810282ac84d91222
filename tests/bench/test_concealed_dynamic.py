"""Motion effects concealed in simulated moving-table recordings (truth: drivers/sim/physics.py).

Scenarios and limits: ``benchmarks/diagnose_dynamic_cases.py`` (docs/diagnose.md). At 10x
its limit on the 90 s oscillation each effect is found and its parameter recovered within
3 of its own sigmas; a concealed low-pass is reported as a delay of its time constant,
named as confounded with ``sensor_lowpass``. Clean oscillation and rate runs report nothing.
"""

from __future__ import annotations

import pytest

from bench.diagnose_recording import diagnose_recording
from benchmarks.diagnose_dynamic_cases import DYNAMIC_CASES, dynamic_z, moving_recording


@pytest.mark.parametrize("effect", ["lever_arm", "time_skew", "sensor_lowpass"])
def test_motion_effect_at_ten_times_its_limit_is_found_and_measured(effect: str) -> None:
    case = DYNAMIC_CASES[effect]
    size = 10 * case.limit
    d = diagnose_recording(moving_recording(case.effects(size), seed=11))
    assert d.method == "dynamic"
    assert [f.effect for f in d.findings] == [case.finding], [f.summary for f in d.findings]
    z = dynamic_z(case, d, size)
    assert z is not None and z < 3.0, z
    if effect == "sensor_lowpass":
        assert d.findings[0].confounded_with == ("sensor_lowpass",)


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
    assert d.findings == () and d.where == "nowhere beyond the noise"
    assert 0.8 < d.final.chi2_dof < 1.2
