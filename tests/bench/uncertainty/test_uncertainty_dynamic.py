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
from bench.uncertainty.dynamic import TILT_ABSORBED, DynamicInput, dynamic_budget, dynamic_inputs
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
