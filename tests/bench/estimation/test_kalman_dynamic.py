"""The extended Kalman filter and RTS smoother of the dynamic model on a drifting sensor."""

from __future__ import annotations

import numpy as np
import pytest

from bench.estimation.dynamic_batch import linear_start, white_sigma
from bench.estimation.dynamic_kalman import Prior, run_dynamic_kalman
from bench.estimation.dynamic_model import ModelSpec, initial_theta
from bench.estimation.motion_data import prepare_motion
from tests.support.dynamic_sim import EFFECTS, oscillation, truth

DRIFT_M_S2_PER_S = np.array([2e-4, -1.5e-4, 1e-4])


def test_smoother_follows_a_drifting_bias() -> None:
    """Bias random walk in the filter; the truth drifts linearly (bias_drift) plus its slow wander."""
    tr = truth(effects={**EFFECTS, "bias_drift": {"drift_m_s2_per_s": DRIFT_M_S2_PER_S.tolist()}})
    run, rec = oscillation(truth=tr)
    m = prepare_motion(rec.t_s, rec.table_rad_unwrapped(), run.axis_vectors, run.mount)
    spec = ModelSpec(("lever_arm", "table_tilt", "time_skew"))
    b0, K0 = linear_start(m, rec.accel_raw, run.g_local_m_s2, np.zeros(3))
    kd = np.diag(tr.K)
    walk = float(np.mean((kd * 3e-4) ** 2))  # (3e-4 m/s²)²/s in channel units
    kr = run_dynamic_kalman(
        m, rec.accel_raw, run.g_local_m_s2, np.zeros(3), spec, initial_theta(spec, b0, K0, np.zeros(3)),
        white_sigma(rec.accel_raw), bias_walk_var_per_s=walk,
    )  # fmt: skip
    k = np.searchsorted(run.t_s, kr.t_s)
    true_b = tr.bias + kd * DRIFT_M_S2_PER_S * kr.t_s[:, None] + (run.bias_wander_m_s2 @ tr.K.T)[k]
    z = (kr.smoothed[:, :3] - true_b) / kr.smoothed_sigma[:, :3]
    assert np.all(np.sqrt(np.mean(z**2, axis=0)) < 1.5) and np.abs(z).max() < 4.0
    # the smoother uses the future too: tighter than the filter
    assert np.median(kr.smoothed_sigma[:, :3] / kr.filtered_sigma[:, :3]) < 0.9
    # the drift itself: slope of the smoothed bias over the run, input-referred (m/s² per s)
    slope = np.polyfit(kr.t_s, kr.smoothed[:, :3] / kd, 1)[0]
    np.testing.assert_allclose(slope, DRIFT_M_S2_PER_S, atol=4e-5)


def test_prior_follows_the_unit_spread() -> None:
    spec = ModelSpec(("lever_arm", "time_skew"))
    K = np.diag([0.0177, 0.0178, 0.0176])
    s = Prior().sigma(spec, K)
    np.testing.assert_allclose(s[:3], 15e-3 * 9.80665 * np.diag(K))  # 15 mg in channel units
    np.testing.assert_allclose(s[3], 0.01 * K[0, 0])  # 1 % scale
    np.testing.assert_allclose(s[4], 15.0 / 60.0 * np.pi / 180.0 * K[0, 0])  # 15′ misalignment
    assert s[spec.index("time_skew")][0] == Prior().delay_s


def test_filter_takes_its_batches_regressors_in_blocks_without_changing_a_bit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The filter takes the regressors of many batches at once (``TAKE_SAMPLES``); the batches see
    the same numbers as one ``take`` per batch (a block of one batch), with the regressors kept or
    formed per pass (``keep_bytes=0``), with and without the skew's derivatives."""
    from bench.estimation import dynamic_kalman

    run, rec = oscillation()
    y, g = rec.accel_raw, run.g_local_m_s2
    q = rec.table_rad_unwrapped()
    for keep_bytes in (None, 0):
        m = prepare_motion(rec.t_s, q, run.axis_vectors, run.mount, keep_bytes=keep_bytes)
        for spec in (ModelSpec(("lever_arm",)), ModelSpec(("lever_arm", "time_skew"))):
            b0, K0 = linear_start(m, y, g, np.zeros(3))
            x0 = initial_theta(spec, b0, K0, np.zeros(3))
            runs = []
            for take in (1, 7 * 10 + 3, dynamic_kalman.TAKE_SAMPLES):
                monkeypatch.setattr(dynamic_kalman, "TAKE_SAMPLES", take)
                runs.append(run_dynamic_kalman(m, y, g, np.zeros(3), spec, x0, white_sigma(y), smooth=False))
            for other in runs[1:]:
                np.testing.assert_array_equal(other.filtered, runs[0].filtered)
                np.testing.assert_array_equal(other.final.P, runs[0].final.P)
