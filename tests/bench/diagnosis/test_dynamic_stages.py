"""The moving recording's selection stages against their rules, on simulated recordings whose
truth is known (``tests/support/diagnose_dynamic_cases.py``)."""

from __future__ import annotations

import numpy as np

from bench.calibration.windows import moving_samples
from bench.diagnosis.dynamic_selection import (
    MOVING,
    MOVING_NO_LIBRARY,
    MovingEvidence,
    MovingState,
    claim_all,
    library_cut,
    motion_selection,
    screen_motion,
)
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


def test_moving_pipelines_share_the_screen_and_the_selection() -> None:
    assert MOVING.stage_names == ("screen_motion", "motion_selection", "library_cut")
    assert MOVING_NO_LIBRARY.stages[:2] == MOVING.stages[:2]
