"""The moving recording's stages against their rules, on simulated recordings whose
truth is known (``tests/support/diagnose_dynamic_cases.py``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.calibration.windows import moving_samples
from bench.diagnosis.dynamic import MOVING, MOVING_ALONE, MOVING_NO_LIBRARY, pipeline_for
from bench.diagnosis.moving_stages import (
    MovingEvidence,
    MovingState,
    bench_physics,
    block_residuals,
    block_unexplained,
    claim_all,
    library_cut,
    motion_selection,
    screen_motion,
)
from bench.diagnosis.pipeline import Pipeline
from bench.diagnosis.thresholds import THRESHOLDS
from bench.estimation.dynamic_model import TERM_ORDER
from tests.support.diagnose_dynamic_cases import DYNAMIC_CASES, moving_recording


def _evidence(effects: dict[str, dict[str, object]], seed: int) -> MovingEvidence:
    rec = moving_recording(effects, seed)
    m, y = moving_samples(rec)
    assert rec.sidecar.table is not None
    lever = np.asarray(rec.sidecar.table.lever_arm_m, dtype=float)
    return MovingEvidence(m, y, rec.sidecar.g_local_m_s2, lever, rec.temp_c)


def test_screen_partitions_the_terms_and_keeps_what_the_oscillation_determines() -> None:
    st, notes = screen_motion(_evidence({}, 3000), MovingState(), THRESHOLDS)
    assert notes == {}
    assert set(st.pool) | set(st.unobservable) == set(TERM_ORDER)
    assert not set(st.pool) & set(st.unobservable)
    # the two-axis oscillation is where the lever arm and the delay are measured (docs/diagnose.md)
    assert {"lever_arm", "time_skew"} <= set(st.pool)


def test_selection_admits_a_strong_delay_and_nothing_on_a_clean_run() -> None:
    case = DYNAMIC_CASES["time_skew"]
    for effects, chosen in ((case.effects(10 * 1.0e-4), ("time_skew",)), ({}, ())):
        ev = _evidence(effects, 3001)
        st, _ = screen_motion(ev, MovingState(), THRESHOLDS)
        st, _ = motion_selection(ev, st, THRESHOLDS)
        assert st.selection is not None and st.selection.chosen == chosen
        # claimed without a library: every step
        out, _ = claim_all(ev, st, THRESHOLDS)
        assert out.claim is not None and out.claim.terms == chosen
        if chosen:
            d = out.claim.fit.theta[out.claim.fit.spec.index("time_skew")][0]
            assert abs(d - 1.0e-3) < 1e-4  # 10 times the detection limit, within a tenth


def test_library_keeps_a_clean_runs_claim_empty() -> None:
    ev = _evidence({}, 3002)
    st, _ = screen_motion(ev, MovingState(), THRESHOLDS)
    st, _ = motion_selection(ev, st, THRESHOLDS)
    st, _ = library_cut(ev, st, THRESHOLDS)
    assert st.claim is not None and st.claim.terms == () and st.claim.library.included == ()


def _claimed_without_library(ev: MovingEvidence) -> MovingState:
    st = MovingState()
    for stage in (screen_motion, motion_selection, claim_all):
        st, _ = stage(ev, st, THRESHOLDS)
    return st


def test_bench_physics_names_a_line_and_no_head_to_head_without_a_claim() -> None:
    # 3 mg at 23.4 Hz on az of an oscillation (the line case of tests/support/families_cases.py)
    line = {"frequency_hz": 23.4, "amplitude_m_s2": [0.0, 0.0, 3e-3 * 9.80665], "phase_rad": 1.0}
    ev = _evidence({"periodic_line": line}, 3003)
    st = _claimed_without_library(ev)
    assert st.claimed.terms == ()
    st, notes = bench_physics(ev, st, THRESHOLDS)
    assert notes == {} and st.families is not None
    found = [f for f in st.families.findings if f.effect == "periodic_line"]
    assert len(found) == 1
    f = found[0].parameters["frequency_hz"]
    assert (
        abs(f - 23.4) < 3 * found[0].sigma["frequency_hz"] + 1e-9 and "az" in found[0].parameters["channels"]
    )
    # nothing claimed: the head to head has nothing to weigh and leaves the state as it is
    out, notes = MOVING_NO_LIBRARY.stages[4](ev, st, THRESHOLDS)
    assert out is st and notes == {} and out.alternative is None


def test_block_stages_see_white_noise_on_a_clean_run() -> None:
    ev = _evidence({}, 3004)
    st = _claimed_without_library(ev)
    st, _ = block_residuals(ev, st, THRESHOLDS)
    assert st.blocks is not None and st.blocks.final_ratio is not None
    # Σ (r / σ_w)² / dof of white noise is 1 (clean simulated recordings: 0.93-1.10, docs/diagnose.md)
    assert np.all(np.abs(st.blocks.final_ratio - 1.0) < 0.15)
    assert st.blocks.baseline.terms[:2] == ("bias", "scale_matrix")
    st, _ = block_unexplained(ev, st, THRESHOLDS)
    assert st.left is None


def test_moving_pipelines_share_the_screen_the_selection_and_the_report() -> None:
    assert MOVING.stage_names == (
        "screen_motion",
        "motion_selection",
        "library_cut",
        "bench_physics",
        "family_head_to_head",
        "block_residuals",
        "block_unexplained",
    )
    assert MOVING_NO_LIBRARY.stage_names[2] == "claim_all"
    assert MOVING_NO_LIBRARY.stages[:2] == MOVING.stages[:2]
    assert MOVING_NO_LIBRARY.stages[3] is MOVING.stages[3]
    assert MOVING_NO_LIBRARY.stages[5:] == MOVING.stages[5:]
    # the head to head's alternative is the same diagnosis without it
    assert MOVING_ALONE.stage_names == tuple(n for n in MOVING.stage_names if n != "family_head_to_head")
    assert pipeline_for(library=True, head_to_head=False) is MOVING_ALONE
    for stage in MOVING.stages + MOVING_NO_LIBRARY.stages:
        assert stage.__doc__ is not None and "Rule:" in stage.__doc__, stage.__name__


def test_a_run_stops_after_the_first_stage_its_condition_holds_for() -> None:
    """``Pipeline.run(until=...)`` (the head to head's run again stops at a selection that cannot
    win): the stages after that one do not run, and the trace ends with it."""
    ran: list[str] = []

    def stage(name: str, pool: tuple[str, ...]):
        def f(ev: object, st: MovingState, th: object) -> tuple[MovingState, dict[str, str]]:
            ran.append(name)
            return replace(st, pool=pool), {name: "ran"}

        f.__name__ = name
        return f

    stages = (stage("a", ()), stage("b", ("time_skew",)), stage("c", ("lever_arm",)))
    pipe = Pipeline("toy", stages)
    st, trace = pipe.run(None, MovingState(), THRESHOLDS, until=lambda s: bool(s.pool))
    assert ran == ["a", "b"] and trace.names == ("a", "b") and st.pool == ("time_skew",)
    assert st.notes == {"a": "ran", "b": "ran"}
    ran.clear()
    st, trace = pipe.run(None, MovingState(), THRESHOLDS)
    assert ran == ["a", "b", "c"] and st.pool == ("lever_arm",)
