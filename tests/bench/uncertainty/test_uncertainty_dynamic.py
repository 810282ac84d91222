"""Budget of a dynamic (moving-table) fit by refitting: closed-form sensitivities on a simulated
oscillation-2axis run, and Type A alone giving U = 2σ."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from bench.calibration.dynamic import DynamicCalibrationResult, calibrate_dynamic
from bench.kinematics import attitude, rot
from bench.recording import Recording
from bench.uncertainty.budget import WANDER_GROUP
from bench.uncertainty.dynamic import TILT_ABSORBED, DynamicInput, dynamic_budget, dynamic_inputs
from bench.uncertainty.wander import run_mean_factor
from tests.support.dynamic_sim import oscillation

DEFAULTS: dict[str, Any] = {
    "angle_u_rad": math.radians(0.001),
    "tilt_u_rad": 1e-5,
    "g_local_u_m_s2": 1e-5,
    "daq": (1e-5, 1e-5),
    "temp_coeff": (5e-4, 3e-5),
}


@pytest.fixture(scope="module")
def fitted() -> tuple[Recording, DynamicCalibrationResult, list[DynamicInput], list[str]]:
    _, rec = oscillation(seed=2)
    fit = calibrate_dynamic(rec)
    assert fit.fit is not None
    inputs, skipped = dynamic_inputs(rec, fit.fit.spec.terms, fit.bias, fit.K, **DEFAULTS)
    return rec, fit, inputs, skipped


def _cov(fit: DynamicCalibrationResult) -> np.ndarray:
    return np.diag(np.concatenate([fit.bias_sigma, fit.K_sigma.ravel()]) ** 2)


def _row(inputs: list[DynamicInput], sens: np.ndarray, name: str) -> np.ndarray:
    return np.asarray(sens[[d.input.name for d in inputs].index(name)])


def test_sensitivities_match_closed_forms(fitted: Any) -> None:
    rec, fit, inputs, skipped = fitted
    assert fit.fit is not None and "table_tilt" in fit.fit.spec.terms
    assert TILT_ABSORBED in skipped
    assert not any(d.input.group.startswith("base levelling") for d in inputs)
    budget = dynamic_budget(rec, fit.fit.spec.terms, fit.bias, fit.K, _cov(fit), inputs)
    g = rec.sidecar.g_local_m_s2
    # raw = b + K f with f ∝ g (the lever arm takes up the motion term): ∂K/∂g = −K/g
    dK = _row(inputs, budget.sensitivity, "local gravity g_local")[3:].reshape(3, 3)
    expected = -fit.K / g
    scale = np.abs(np.diag(expected))[:, None]
    assert np.all(np.abs(dK - expected) <= 0.03 * scale)
    assert np.allclose(_row(inputs, budget.sensitivity, "local gravity g_local")[:3], 0.0, atol=1e-3)
    for i, letter in enumerate("xyz"):
        off = _row(inputs, budget.sensitivity, f"DAQ offset, channel {letter}")
        assert off[i] == pytest.approx(1.0, abs=1e-4)
        assert np.allclose(np.delete(off[:3], i), 0.0, atol=1e-4)
        assert np.allclose(off[3:], 0.0, atol=1e-4 * np.abs(fit.K).max())
        # raw_i (1 + ε): row i of b and K scale by 1 + ε
        gain = _row(inputs, budget.sensitivity, f"DAQ gain, channel {letter}")
        assert gain[i] == pytest.approx(fit.bias[i], rel=1e-3)
        assert np.allclose(gain[3:].reshape(3, 3)[i], fit.K[i], rtol=0.02, atol=1e-3 * abs(fit.K[i, i]))
    b_x = budget.by_name("b_x")
    by_name = {c.name: c for c in b_x.contributions}
    assert by_name["DAQ gain, channel x"].contribution == pytest.approx(1e-5 * abs(fit.bias[0]), rel=1e-3)
    assert b_x.k == 2.0
    assert math.isclose(b_x.U, 2 * b_x.u_c)
    assert b_x.u_c > fit.bias_sigma[0]


def test_zero_type_b_gives_two_sigma(fitted: Any) -> None:
    rec, fit, _, _ = fitted
    zero = {**DEFAULTS, "angle_u_rad": 0.0, "tilt_u_rad": 0.0, "g_local_u_m_s2": 0.0,
            "daq": (0.0, 0.0), "temp_coeff": (0.0, 0.0)}  # fmt: skip
    assert fit.fit is not None
    inputs, _ = dynamic_inputs(rec, fit.fit.spec.terms, fit.bias, fit.K, **zero)
    budget = dynamic_budget(rec, fit.fit.spec.terms, fit.bias, fit.K, _cov(fit), inputs)
    sigma = np.concatenate([fit.bias_sigma, fit.K_sigma.ravel()])
    assert np.allclose([q.U for q in budget.quantities], 2 * sigma, rtol=1e-12)
    assert all(q.k == 2.0 for q in budget.quantities)


def test_bad_covariance_is_refused(fitted: Any) -> None:
    rec, fit, inputs, _ = fitted
    assert fit.fit is not None
    with pytest.raises(ValueError, match="Type A covariance"):
        dynamic_budget(rec, fit.fit.spec.terms, fit.bias, fit.K, np.full((12, 12), np.nan), inputs)


def test_levelling_inputs_tilt_the_whole_table_when_the_fit_does_not(fitted: Any) -> None:
    rec, fit, _, _ = fitted
    terms = tuple(t for t in fit.fit.spec.terms if t != "table_tilt")
    inputs, skipped = dynamic_inputs(rec, terms, fit.bias, fit.K, **DEFAULTS)
    assert TILT_ABSORBED not in skipped
    lev = next(d for d in inputs if d.input.name == "base levelling about x")
    h = 1e-3
    moved = lev.change(rec, h)
    q = rec.table_rad_unwrapped()[::500]
    geo, new = rec.sidecar.table, moved.sidecar.table
    T = rot(np.eye(3)[0], h)[0]
    # T Rot(u_1, θ_1)…Rot(u_k, θ_k) M = Rot(T u_1, θ_1)…Rot(T u_k, θ_k) T M at every sample
    expected = np.einsum("ab,nbc->nac", T, attitude(geo.axis_vectors, q, geo.mount_matrix))
    np.testing.assert_allclose(attitude(new.axis_vectors, q, new.mount_matrix), expected, atol=1e-12)


@pytest.mark.parametrize(("span_s", "tc_s"), [(167.0, 200.0), (600.0, 200.0), (6000.0, 50.0), (20.0, 2000.0)])
def test_run_mean_factor_is_the_variance_of_a_gauss_markov_time_average(span_s: float, tc_s: float) -> None:
    """r(T)² against the double integral (1/T²) ∫∫ e^(−|t−s|/T_c) dt ds by the midpoint rule
    (4000 points: relative error < 1e-4 here), and the limits 2T_c/T (T ≫ T_c) and 1 (T ≪ T_c)."""
    n = 4000
    t = (np.arange(n) + 0.5) * span_s / n
    numeric = float(np.mean(np.exp(-np.abs(t[:, None] - t[None, :]) / tc_s)))
    r = run_mean_factor(span_s, tc_s)
    assert r**2 == pytest.approx(numeric, rel=2e-3)
    if span_s > 50 * tc_s:
        assert r**2 == pytest.approx(2 * tc_s / span_s, rel=0.05)
    if span_s < 0.02 * tc_s:
        assert r**2 == pytest.approx(1.0, abs=0.01)


def test_wander_line_replaces_the_bias_type_a_by_the_run_mean_and_adds_the_wander(
    fitted: tuple[Recording, DynamicCalibrationResult, list[DynamicInput], list[str]],
) -> None:
    """With the unit's wander: the bias's Type A is the fit's sigma against the run's mean,
    a line per sensor axis carries |K_ij| r(T) σ_w, and K's lines are as without it."""
    rec, fit, _, _ = fitted
    assert fit.fit is not None
    level, tc = 4e-4, 200.0
    plain = dynamic_budget(rec, fit.fit.spec.terms, fit.bias, fit.K, _cov(fit), [])
    withw = dynamic_budget(
        rec, fit.fit.spec.terms, fit.bias, fit.K, _cov(fit), [],
        wander=(level, tc), bias_sigma_run_mean=fit.fit.bias_sigma_run_mean,
    )  # fmt: skip
    r = run_mean_factor(float(rec.t_s[-1] - rec.t_s[0]), tc)
    for i in range(3):
        q = withw.quantities[i]
        type_a = next(c for c in q.contributions if c.group == "Type A")
        assert type_a.u == pytest.approx(fit.fit.bias_sigma_run_mean[i], rel=1e-9)
        lines = [c for c in q.contributions if c.group == WANDER_GROUP]
        assert [c.contribution for c in lines] == pytest.approx(np.abs(fit.K[i]) * r * level, rel=1e-9)
        expected = math.sqrt(fit.fit.bias_sigma_run_mean[i] ** 2 + float(np.sum((fit.K[i] * r * level) ** 2)))
        assert q.u_c == pytest.approx(expected, rel=1e-9)
    for j in range(3, 12):
        assert withw.quantities[j].u_c == pytest.approx(plain.quantities[j].u_c, rel=1e-9)
