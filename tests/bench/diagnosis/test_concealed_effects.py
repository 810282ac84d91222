"""Effects concealed in simulated static-12 recordings (truth model: drivers/sim/physics.py).

Scenarios and measured detection limits: ``benchmarks/diagnose_cases.py`` (the full table,
more recordings per cell: ``python -m benchmarks.study_diagnose_detection``, docs/diagnose.md).
At 10x its limit each effect must be found and its parameter recovered within 3 of its own
sigmas; at 3x it must be found in at least the stated share of recordings. On 100 clean
recordings the count with a finding stays within a binomial margin of the design's nominal rate.
"""

from __future__ import annotations

import math

import pytest
from scipy.stats import binom

from bench.calibration.diagnose import diagnose_recording
from bench.diagnosis.thresholds import Thresholds
from tests.support.diagnose_cases import CASES, clean_finding_rate, run_case, static_recording

TEN_X = ["nonlinearity_quadratic", "scale_asymmetry", "cross_coupling", "temperature_bias", "bias_drift",
         "table_tilt", "pose_error", "encoder_offset", "settling"]  # fmt: skip
THREE_X_SEEDS = range(21, 25)
THREE_X_MIN_FOUND = 3
"""At 3x the limit an effect is found in at least 3 of these 4 recordings (the study finds >= 90 %)."""
POSE_THREE_X_RATE = 0.45
"""Share of static-12 recordings in which pose_error at 3x its limit is found: 54 of 120 (seeds
200-319, ``python -m benchmarks.study_sampled_rates pose``, 95 % interval 36-54 %, docs/diagnose.md)."""
POSE_THREE_X_SEEDS = range(21, 61)


@pytest.mark.slow
@pytest.mark.parametrize("effect", TEN_X)
def test_effect_at_ten_times_its_limit_is_found_and_measured(effect: str) -> None:
    case = CASES[effect]
    s = run_case(case, 10 * case.limit, seed=11)
    assert s.found, f"{effect} not found at 10x its limit; other findings {s.others}"
    assert abs(s.z) < 3.0, f"{effect}: parameter off by {s.z:.1f} sigma"


@pytest.mark.slow
@pytest.mark.parametrize("effect", [e for e in TEN_X if e != "pose_error"])
def test_effect_at_three_times_its_limit_is_found_mostly(effect: str) -> None:
    case = CASES[effect]
    scores = [run_case(case, 3 * case.limit, seed=s) for s in THREE_X_SEEDS]
    found = sum(s.found for s in scores)
    assert found >= THREE_X_MIN_FOUND, f"{effect} found in {found} of {len(scores)} at 3x"
    assert all(abs(s.z) < 4.0 for s in scores if s.found and not math.isnan(s.z))


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_pose_error_at_three_times_its_limit_is_found_at_its_measured_rate() -> None:
    """pose_error at 3x its limit is found on only part of the recordings: the count over the
    40 seeds 21-60 may fall to the 0.1 % point of Bin(40, ``POSE_THREE_X_RATE``) (the rate
    measured over the study's seeds, which these do not share), 9 at 0.45, and no lower: a true
    rate of 20 % fails it with probability 0.59, of 15 % with 0.86.
    Where found, the angles are within 4 of their sigmas (RMS over the windows)."""
    case = CASES["pose_error"]
    n = len(POSE_THREE_X_SEEDS)
    need = binom.ppf(0.001, n, POSE_THREE_X_RATE)
    scores = [run_case(case, 3 * case.limit, seed=s) for s in POSE_THREE_X_SEEDS]
    found = sum(s.found for s in scores)
    assert found >= need, f"pose_error found in {found} of {n} at 3x (at least {need:.0f})"
    assert all(abs(s.z) < 4.0 for s in scores if s.found and not math.isnan(s.z))


@pytest.mark.slow
def test_false_finding_rate_on_a_hundred_clean_recordings() -> None:
    """Clean recordings with any finding stay within the design's rate: nominal p0 =
    ``clean_finding_rate`` (tests/support/diagnose_cases.py: 0.01 + 0.001 + 0.001 = 0.012 at
    the defaults), n = 100, and the count may reach the 99.9 % point of Bin(n, p0) (6 at the
    defaults), a margin over the nominal rate rather than the rate measured (3 of 250, 1.2 %,
    docs/diagnose.md). Power: at a true rate of 8 % it fails with probability 0.70."""
    n = 100
    bound = binom.ppf(0.999, n, clean_finding_rate(Thresholds()))
    false = {}
    for seed in range(1000, 1000 + n):
        effects = [f.effect for f in diagnose_recording(static_recording({}, seed=seed)).findings]
        if effects:
            false[seed] = effects
    assert len(false) <= bound, (bound, false)


def test_drift_on_the_lab_default_is_reported_as_confounded_with_warm_up_temperature() -> None:
    """Lab default temperature (warm-up): drift and temperature_bias look alike; the finding says so.

    The drift (4e-5 m/s²/s) is well above what the slow wander can make: at 2e-5 this seed sat
    at the gate (own-wander likelihood ratio 16.9 against 17.0, then 17.4 once the step shares
    its α with thermal_lag's candidates), which is a question of power, not of what the finding
    says (4e-5: bias_drift named with temperature_bias as its twin on seeds 11-16)."""
    d = diagnose_recording(static_recording({"bias_drift": {"drift_m_s2_per_s": [4e-5, 0.0, 0.0]}}, seed=11))
    f = next(f for f in d.findings if f.effect in ("bias_drift", "temperature_bias"))
    other = "temperature_bias" if f.effect == "bias_drift" else "bias_drift"
    assert other in f.confounded_with and "temperature follows time" in f.summary
