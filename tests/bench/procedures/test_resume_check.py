"""The check a resume passes: the stored procedure is known and rebuilds, and what remains of
it — the move to the next window's pose and every step from that window on — fits the table's
limits now; windows already recorded are not walked again."""

from __future__ import annotations

from bench.procedures import (
    DEFAULT_TABLE_LIMITS,
    Admitted,
    Refusal,
    RefusalKind,
    TableLimits,
    build_procedure,
)
from bench.procedures.preview import preview
from bench.procedures.resume_check import check_resume, remaining, stored_parameters

RUN = "run-7"


def refused(checked: Admitted | Refusal) -> Refusal:
    assert isinstance(checked, Refusal), checked
    return checked


def test_a_rate_the_table_no_longer_reaches_refuses_only_the_resumes_that_still_turn_at_it() -> None:
    """rate-1axis at 1000 then 100 deg/s on a 300 deg/s outer axis (a run stored where the limit
    was higher): each of the six poses records static, +1000, +100, so a resume at window w has
    as many refused rotations as +1000 windows at or after w; after the last one it is admitted."""
    stored = {"dwell_s": 5.0, "rates_deg_s": [1000.0, 100.0]}
    for next_window in range(18):
        checked = check_resume(
            "rate-1axis", DEFAULT_TABLE_LIMITS, stored=stored, next_window=next_window, run_id=RUN
        )
        still_fast = sum(1 for w in range(next_window, 18) if w % 3 == 1)
        if still_fast == 0:
            assert isinstance(checked, Admitted), (next_window, checked)
            assert checked.procedure.n_windows == 18 and len(checked.preview.windows) == 18 - next_window
            continue
        r = refused(checked)
        assert r.kind is RefusalKind.TABLE_LIMITS and r.preview is not None
        assert len(r.preview.problems) == still_fast, (next_window, r.preview.problems)
        assert r.message.startswith(
            f"run {RUN}: the {18 - next_window} windows of rate-1axis still to record"
        )
        assert "rate 1000 deg/s exceeds the axis 1 limit 300 deg/s" in r.message


def test_poses_outside_a_narrowed_travel_are_refused_by_the_windows_that_remain() -> None:
    """static-12 on a table whose middle axis travels only ±100 deg: the refusal names exactly
    the remaining windows' poses whose middle angle is outside, found here from the full
    walk's window poses (each static window is reached by the move of the same label)."""
    limits = TableLimits(
        pos_lo_deg=(-180.0, -100.0, -180.0),
        pos_hi_deg=(180.0, 100.0, 180.0),
        max_rate_deg_s=(300.0,) * 3,
        max_acc_deg_s2=(200.0,) * 3,
        continuous=(True, False, True),
    )
    windows = preview(build_procedure("static-12", dwell_s=5.0)).windows
    assert any(abs(w.pose_deg[1]) > 100.0 for w in windows) and abs(windows[-1].pose_deg[1]) > 100.0
    for next_window in range(12):
        outside = [w.label for w in windows[next_window:] if abs(w.pose_deg[1]) > 100.0]
        r = refused(
            check_resume("static-12", limits, stored={"dwell_s": 5.0}, next_window=next_window, run_id=RUN)
        )
        assert r.kind is RefusalKind.TABLE_LIMITS and r.preview is not None
        named = [p.split("(MoveTo ", 1)[1].split(")", 1)[0] for p in r.preview.problems]
        assert named == outside, (next_window, named, outside)
        assert all("axis 2 angle" in p and "outside [-100, 100] deg" in p for p in r.preview.problems)
    assert isinstance(
        check_resume("static-12", limits, stored={"dwell_s": 5.0}, next_window=12, run_id=RUN), Admitted
    )


def test_an_unknown_procedure_names_the_run_and_the_known_ones() -> None:
    r = refused(check_resume("static-13", DEFAULT_TABLE_LIMITS, stored={}, next_window=3, run_id=RUN))
    assert r.kind is RefusalKind.UNKNOWN_PROCEDURE and r.procedure == "static-13"
    assert r.message.startswith(
        f"run {RUN} was recorded with procedure 'static-13', which this calbench does not know"
    )
    assert "static-12" in r.message
    assert isinstance(stored_parameters("static-13", {}, RUN), Refusal)


def test_stored_parameters_the_factory_no_longer_accepts_are_a_bad_value() -> None:
    r = refused(
        check_resume(
            "rate-1axis", DEFAULT_TABLE_LIMITS, stored={"rates_deg_s": []}, next_window=0, run_id=RUN
        )
    )
    assert r.kind is RefusalKind.BAD_VALUE
    assert r.message == (
        f"run {RUN}: procedure 'rate-1axis' does not rebuild from its stored parameters: "
        "rate-1axis: rates_deg_s is empty"
    )
    past = refused(
        check_resume("static-12", DEFAULT_TABLE_LIMITS, stored={"dwell_s": 5.0}, next_window=14, run_id=RUN)
    )
    assert past.kind is RefusalKind.BAD_VALUE and "cannot resume at window 14 of 12" in past.message


def test_what_remains_starts_with_the_move_to_the_next_windows_pose() -> None:
    proc = build_procedure("static-12", dwell_s=5.0)
    rest = remaining(proc, 4)
    start, move = proc.resume_plan(4)
    assert move is not None and rest.steps == (proc.steps[move], *proc.steps[start:])
    assert rest.n_windows == 8
    assert remaining(proc, 12).steps == ()
