"""Observability: Fisher-information rank, the undetermined parameters named, plans checked."""

from __future__ import annotations

import numpy as np
import pytest

from bench.estimation.observability import check_information, information_report
from bench.procedures.observability import plan_observability, procedure_angles
from bench.procedures.oscillation import oscillation_2axis
from bench.procedures.rate import rate_1axis
from bench.procedures.steps import Dwell, MoveTo, Procedure, Rotate


def test_full_rank_bound_is_the_inverse_information() -> None:
    rng = np.random.default_rng(0)
    J = rng.standard_normal((50, 3)) * [1.0, 1e-3, 1e4]  # parameters in very different units
    F = J.T @ J
    rep = information_report(F, ["a", "b", "c"])
    assert rep.ok and rep.rank == 3
    np.testing.assert_allclose(rep.crb_sigma, np.sqrt(np.diag(np.linalg.inv(F))), rtol=1e-9)


def test_zero_column_and_combination_are_named() -> None:
    rng = np.random.default_rng(1)
    x = rng.standard_normal((40, 2))
    J = np.column_stack([x[:, 0], x[:, 1], 2.0 * x[:, 1], np.zeros(40)])
    rep = information_report(J.T @ J, ["bias_x", "K_xx", "r_x", "delay_s"])
    assert not rep.ok and rep.rank == 2
    text = " | ".join(rep.unobservable)
    assert "delay_s: no information" in text
    assert "K_xx" in text and "r_x" in text and "only a combination" in text
    assert "bias_x" not in text
    with pytest.raises(ValueError, match="delay_s"):
        check_information(J.T @ J, ["bias_x", "K_xx", "r_x", "delay_s"])


def test_oscillation_plan_determines_every_term() -> None:
    rep, why = plan_observability(
        oscillation_2axis(dwell_s=10.0), ("lever_arm", "nonlinearity_quadratic", "table_tilt", "time_skew")
    )
    assert rep.ok and why == {}
    # the paper's radius vector to ~1 mm: the bound is well below
    assert np.max(rep.crb_sigma[12:15]) < 1e-3


def test_single_pose_rate_plan_cannot_determine_scale() -> None:
    proc = rate_1axis(dwell_s=10.0, poses_deg=((0.0, 0.0),))
    rep, why = plan_observability(proc, ("lever_arm",))
    assert not rep.ok
    assert "scale_matrix" in why and "no information" in why["scale_matrix"]


UP_ONLY_POSES_DEG = ((0.0, 0.0), (90.0, 90.0), (90.0, 0.0))


def test_tilted_rate_plan_determines_proof_masses() -> None:
    terms = ("proof_mass_offsets", "nonlinearity_quadratic")
    _, up_only = plan_observability(rate_1axis(dwell_s=10.0, poses_deg=UP_ONLY_POSES_DEG), terms)
    _, tilted = plan_observability(rate_1axis(dwell_s=10.0, tilted_deg=10.0), terms)
    assert "nonlinearity_quadratic" in up_only  # every axis only ever points up at a pose
    assert tilted == {}


def test_default_rate_plan_points_each_axis_up_and_down() -> None:
    up_only, _ = plan_observability(rate_1axis(dwell_s=10.0, poses_deg=UP_ONLY_POSES_DEG), ("lever_arm",))
    both, why = plan_observability(rate_1axis(dwell_s=10.0), ("lever_arm", "nonlinearity_quadratic"))
    assert both.ok and why == {}
    # bias and scale bounds (first 12 parameters) tighten by far more than the doubled duration gives
    assert np.all(both.crb_sigma[:12] < up_only.crb_sigma[:12] / 3.0)


def test_procedure_angles_follow_the_steps() -> None:
    proc = Procedure(
        "t",
        (MoveTo((0.0, 90.0, 0.0), settle_s=1.0), Dwell("a", 2.0), Rotate(1, 100.0, 3.0, spinup_s=2.0)),
        {},
        3,
    )
    t, q = procedure_angles(proc, 100.0, accel_deg_s2=100.0)
    assert np.allclose(np.diff(t), 0.01)
    qd = np.rad2deg(q)
    assert np.isclose(qd[-1, 1], 90.0) and np.isclose(qd[-1, 2], 0.0)
    # ramp 1 s, 100 deg/s held for spin-up + window (5 s), ramp 1 s: 600 deg turned in all
    assert np.isclose(qd[-1, 0], 600.0, atol=1.0)


def test_preview_refuses_a_motion_that_cannot_calibrate() -> None:
    from bench.procedures import preview

    assert preview(rate_1axis(dwell_s=10.0)).ok
    pv = preview(rate_1axis(dwell_s=10.0, poses_deg=((0.0, 0.0),)))
    assert not pv.ok
    assert any("cannot determine scale_matrix" in p for p in pv.problems)
