"""The one check a request to run a procedure passes: each refusal kind names what and why,
and an admitted request carries the procedure and its walk on the table."""

from __future__ import annotations

import pytest

from bench.procedures import (
    DEFAULT_TABLE_LIMITS,
    Admitted,
    ProcedureRefused,
    Refusal,
    RefusalKind,
    TableLimits,
    admit_procedure,
    check_procedure,
)

ONE_AXIS = TableLimits((-180.0,), (180.0,), (300.0,), (200.0,), (True,))


def refused(checked: Admitted | Refusal) -> Refusal:
    assert isinstance(checked, Refusal), checked
    return checked


def test_a_runnable_request_is_admitted_with_its_walk() -> None:
    """static-12 at a 5 s dwell: twelve static windows of 5 s, nothing the table refuses."""
    checked = check_procedure("static-12", DEFAULT_TABLE_LIMITS, dwell_s=5.0)
    assert isinstance(checked, Admitted)
    assert checked.procedure.name == "static-12"
    assert [w.duration_s for w in checked.preview.windows] == [5.0] * 12
    assert checked.preview.problems == ()


def test_an_unknown_name_is_refused_listing_the_known_ones() -> None:
    r = refused(check_procedure("static-13", DEFAULT_TABLE_LIMITS))
    assert r.kind is RefusalKind.UNKNOWN_PROCEDURE
    assert r.procedure == "static-13"
    assert r.message == (
        "unknown procedure 'static-13'; known: "
        "oscillation-2axis, planned-static, planned-tumble, rate-1axis, static-12"
    )
    assert r.preview is None


def test_a_parameter_the_procedure_does_not_take_is_named() -> None:
    r = refused(check_procedure("static-12", DEFAULT_TABLE_LIMITS, parameters={"rates_deg_s": (10.0,)}))
    assert r.kind is RefusalKind.UNKNOWN_PARAMETER
    assert r.message.startswith("procedure 'static-12' takes no parameter rates_deg_s; it takes: ")


def test_a_value_the_factory_refuses_is_a_bad_value() -> None:
    r = refused(check_procedure("static-12", DEFAULT_TABLE_LIMITS, dwell_s=-1.0))
    assert r.kind is RefusalKind.BAD_VALUE
    assert "must be > 0, got -1.0" in r.message


def test_a_walk_the_table_limits_refuse_keeps_its_preview() -> None:
    """A 1000 deg/s rate on an axis limited to 300 deg/s; a 3-axis procedure on a 1-axis table."""
    r = refused(
        check_procedure(
            "rate-1axis", DEFAULT_TABLE_LIMITS, dwell_s=5.0, parameters={"rates_deg_s": (1000.0,)}
        )
    )
    assert r.kind is RefusalKind.TABLE_LIMITS
    assert r.message.startswith("rate-1axis: step 2 (Rotate pose1-rate+1000): rate 1000 deg/s exceeds")
    assert r.preview is not None and len(r.preview.problems) == 6  # one rotation per pose
    axes = refused(check_procedure("static-12", ONE_AXIS, dwell_s=5.0))
    assert axes.kind is RefusalKind.TABLE_LIMITS
    assert "static-12 needs a 3-axis table, the table has 1 axes" in axes.message


def test_admit_raises_the_refusal_as_a_value_error() -> None:
    with pytest.raises(ValueError, match="unknown procedure 'nope'") as info:
        admit_procedure("nope", DEFAULT_TABLE_LIMITS)
    assert isinstance(info.value, ProcedureRefused)
    assert info.value.refusal.kind is RefusalKind.UNKNOWN_PROCEDURE
    admitted = admit_procedure("static-12", DEFAULT_TABLE_LIMITS, dwell_s=5.0)
    assert admitted.procedure.n_windows == 12


def test_every_procedure_is_named_moving_or_static_once() -> None:
    """The fit kind's name lists (``bench.calibration.kind``) cover the registry exactly."""
    from bench.calibration.kind import MOVING_PROCEDURES, STATIC_PROCEDURES
    from bench.procedures.registry import PROCEDURES

    assert set(MOVING_PROCEDURES) | set(STATIC_PROCEDURES) == set(PROCEDURES)
    assert not set(MOVING_PROCEDURES) & set(STATIC_PROCEDURES)
