"""Deviations from the procedure and the run record, from a run's audit trail and gaps."""

from __future__ import annotations

import datetime as dt

from bench.run_state import RunState
from station.certificates.deviations import no_deviation, run_deviations, run_record_section, started_by
from station.certificates.inputs import ActionFact, RunFacts

T0 = dt.datetime(2026, 11, 20, 8, 0, 0, tzinfo=dt.UTC)


def _at(s: float) -> dt.datetime:
    return T0 + dt.timedelta(seconds=s)


def _state(
    s: float, state: str, detail: str = "", window: int | None = None, actor: str = "agent"
) -> ActionFact:
    return ActionFact(_at(s), actor, "state", RunState(state), detail, window)


COURSE = (
    ActionFact(_at(0), "Ada Lovelace", "start", detail="static-12"),
    _state(2, "running", "started", 0),
    ActionFact(_at(40), "Grace Hopper", "pause"),
    _state(41, "paused", "operator pause", 3),
    ActionFact(_at(100), "Ada Lovelace", "continue"),
    _state(101.4, "running", "resumed after: operator pause", 3),
    _state(200, "suspended", "interlock open", 6),
    _state(212.6, "running", "resumed after: interlock open", 6),
    _state(300, "interrupted", "owner process 4242 on bench-pc is gone", 8, actor="system"),
    ActionFact(_at(900), "Grace Hopper", "resume", detail="from window 8", window_index=8),
    _state(905, "running", "resumed from window 8", 8),
    _state(1400, "completed", "outcome PASS"),
)
GAP = {
    "n_lost": 12,
    "cause": "dropped",
    "t_last_s": 52.5,
    "window_index": 4,
    "window_label": "pos05",
    "action": "window re-measured",
}


def test_every_hold_interruption_resume_and_gap_in_order() -> None:
    got = run_deviations(RunFacts(id="R", actions=COURSE, sample_gaps=[GAP]))
    assert got == [
        "paused by the operator for 60 s from 2026-11-20 08:00:41 UTC at window 3 (asked by Grace Hopper "
        "at 2026-11-20 08:00:40 UTC); the interrupted step was executed again, no sample of the hold is "
        "in a window",
        "suspended automatically for 13 s from 2026-11-20 08:03:20 UTC at window 6: interlock open; the "
        "interrupted step was executed again, no sample of the hold is in a window",
        "interrupted at 2026-11-20 08:05:00 UTC at window 8: owner process 4242 on bench-pc is gone",
        "resumed at window 8 on request of Grace Hopper at 2026-11-20 08:15:00 UTC: the windows before it "
        "were kept, the recording after the last complete window was cut and recorded again",
        "12 samples lost (dropped) after 52.500 s of the recording, in window 4 (pos05): window re-measured",
    ]


def test_a_hold_never_continued_says_so() -> None:
    course = (*COURSE[:4], _state(50, "aborted", "aborted at step 9"))
    (line,) = run_deviations(RunFacts(actions=course))
    assert line.startswith("paused by the operator for 9 s")
    (line,) = run_deviations(RunFacts(actions=COURSE[:4]))
    assert "until the run ended (not continued)" in line


def test_a_straight_run_says_what_was_checked_and_an_old_one_that_nothing_was_kept() -> None:
    straight = RunFacts(actions=(COURSE[0], COURSE[1], COURSE[-1]))
    assert run_deviations(straight) == []
    assert no_deviation(straight).startswith("none: the run was neither paused, suspended nor interrupted")
    assert no_deviation(RunFacts()).startswith("not recorded")


def test_who_started_the_run_and_the_record() -> None:
    run = RunFacts(actions=COURSE)
    assert started_by(run) == "Ada Lovelace at 2026-11-20 08:00:00 UTC"
    record = run_record_section(run)
    assert len(record["actions"]) == len(COURSE)
    assert record["actions"][2] == "2026-11-20 08:00:40 UTC  Grace Hopper: pause requested"
    assert record["actions"][3] == "2026-11-20 08:00:41 UTC  agent: state paused (operator pause)"
    assert started_by(RunFacts()).startswith("not recorded")


def test_a_withdrawn_verdict_is_in_the_record_and_no_deviation() -> None:
    withdrawn = ActionFact(
        _at(5000),
        "migration 0006",
        "withdraw",
        detail="PASS withdrawn: judged against model ADXL325's limits",
    )
    run = RunFacts(id="R", actions=(*COURSE, withdrawn), sample_gaps=[GAP])
    assert run_deviations(run) == run_deviations(RunFacts(id="R", actions=COURSE, sample_gaps=[GAP]))
    assert run_record_section(run)["actions"][-1] == (
        "2026-11-20 09:23:20 UTC  migration 0006: statement of conformity withdrawn "
        "(PASS withdrawn: judged against model ADXL325's limits)"
    )
