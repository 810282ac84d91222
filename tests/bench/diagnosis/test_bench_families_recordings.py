"""Bench physics concealed by the truth model and diagnosed from whole recordings (slow).

Rates measured by ``benchmarks/study_diagnose_families.py`` (docs/diagnose.md, "Bench physics
beyond the catalogue"); here a sample of its cases on seeds 100-102, each asked to be named
with nothing else claimed in at least 2 of 3 (the study: all of 3 or 5 for each case here), and clean
recordings of each kind with no bench-family finding.
"""

from __future__ import annotations

import pytest

from bench.calibration.diagnose import diagnose_recording
from bench.diagnosis.effects import CATALOGUE
from tests.support.diagnose_cases import static_recording
from tests.support.diagnose_dynamic_cases import moving_recording
from tests.support.families_cases import cases

SAMPLED = (
    "table_axis_error: middle axis 0.05° off perpendicular",
    "angle_harmonic: outer axis, 2 per turn, ay, rate table, 1.0 mg",
    "angle_harmonic: inner axis, once per turn, ax, oscillation, 1.0 mg",
    "periodic_line: 0.5 Hz on ax, static, 1.0 mg",
    "periodic_line: 23.4 Hz on az, oscillation, 1.0 mg",
    "clock_drift: 100 ppm, oscillation",
    "clock_drift: 100 ppm, rate",
    "hysteresis: axis 3, ay, static, 300 µg",
)
CATALOGUE_IDS = {e.id for e in CATALOGUE}


@pytest.mark.slow
@pytest.mark.parametrize("name", SAMPLED)
def test_family_is_named_and_nothing_else_claimed(name: str) -> None:
    (case,) = [c for c in cases() if c.name == name]
    good = 0
    for seed in (100, 101, 102):
        d = diagnose_recording(case.recording(seed))
        ok, _ = case.score(d, case.truth(seed), case.size)
        good += ok and not case.claimed(d)
    assert good >= 2


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["static", "rate", "oscillation"])
def test_clean_recordings_carry_no_bench_family(kind: str) -> None:
    for seed in (1000, 1001, 1002):
        rec = static_recording({}, seed) if kind == "static" else moving_recording({}, seed, kind)
        d = diagnose_recording(rec)
        assert [f.effect for f in d.findings if f.effect not in CATALOGUE_IDS] == []
