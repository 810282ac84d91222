"""RunControl at the end of the steps: an abort that came first wins, any later one is refused."""

from __future__ import annotations

from bench.sequencer.control import RunControl


def test_an_abort_before_finishing_ends_the_run_aborted() -> None:
    control = RunControl()
    assert control.abort("operator")
    assert control.enter_finishing() == "operator"
    assert not control.finishing


def test_requests_after_finishing_are_refused_and_change_nothing() -> None:
    control = RunControl()
    assert control.enter_finishing() is None and control.finishing
    assert not control.abort("too late") and not control.abort_requested
    assert not control.pause() and not control.pause_requested


def test_the_gate_reports_an_abort_stored_elsewhere() -> None:
    control = RunControl()
    control.finishing_gate = lambda: "abort stored in the database"
    assert control.enter_finishing() == "abort stored in the database"
    assert control.abort_requested and control.abort_reason == "abort stored in the database"
