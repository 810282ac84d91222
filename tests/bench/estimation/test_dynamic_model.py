"""The dynamic measurement model against the simulator's independent physics, and its Jacobian."""

from __future__ import annotations

import numpy as np
import pytest

from bench.estimation.dynamic_model import TERM_ORDER, ModelSpec, initial_theta, predict
from bench.estimation.motion_data import prepare_motion, window_samples
from tests.support.dynamic_sim import DELAY_TRUE_S, R_TRUE_M, TILT_TRUE_RAD, oscillation, rate, truth

RHO = np.array([[0.0, 0.004, -0.002], [0.003, 0.0, 0.001], [-0.002, 0.002, 0.0]])
K2 = np.array([1.5e-3, -1e-3, 5e-4])


def _theta_true(run, spec: ModelSpec) -> np.ndarray:  # type: ignore[no-untyped-def]
    th = initial_theta(spec, run.truth.bias, run.truth.K, R_TRUE_M)
    for t in spec.terms:
        s = spec.index(t)
        if t == "proof_mass_offsets":
            th[s] = (R_TRUE_M + RHO).reshape(9)
        elif t == "nonlinearity_quadratic":
            th[s] = K2
        elif t == "table_tilt":
            th[s] = TILT_TRUE_RAD
        elif t == "time_skew":
            th[s] = DELAY_TRUE_S
    return th


@pytest.mark.parametrize(
    ("make", "kw"), [(oscillation, {}), (rate, {}), (oscillation, {"rate_hz": 1000.0, "duration_s": 30.0})]
)
def test_noise_free_prediction_matches_simulator(make, kw) -> None:  # type: ignore[no-untyped-def]
    effects = {
        "lever_arm": {"r_m": R_TRUE_M.tolist()},
        "proof_mass_offsets": {"rho_m": RHO.tolist()},
        "nonlinearity_quadratic": {"k2_per_g": K2.tolist()},
        "table_tilt": {"tilt_rad": TILT_TRUE_RAD.tolist()},
        "time_skew": {"delay_s": DELAY_TRUE_S},
    }
    run, rec = make(truth=truth(effects=effects, noiseless=True), **kw)
    m = prepare_motion(rec.t_s, rec.table_rad_unwrapped(), run.axis_vectors, run.mount)
    spec = ModelSpec(TERM_ORDER)
    raw, _ = predict(_theta_true(run, spec), m, spec, run.g_local_m_s2, np.zeros(3))
    err = (raw - run.raw)[m.valid]
    scale = np.diag(run.truth.K)
    # input-referred error below 2e-5 m/s² (2 µg; 5e-7 m/s² at 100 Hz, 9e-6 m/s² at 1 kHz), against
    # signals of ~1 g and motion terms of up to 0.3 g
    assert np.max(np.abs(err) / scale) < 2e-5
    # the masked samples are few: corners of the trapezoidal moves only
    assert m.valid.mean() > 0.97
    # and without the effects the model misses by far more (the check can fail)
    bare = ModelSpec(())
    raw0, _ = predict(
        initial_theta(bare, run.truth.bias, run.truth.K, np.zeros(3)), m, bare, run.g_local_m_s2, np.zeros(3)
    )
    assert np.max(np.abs((raw0 - run.raw)[m.valid]) / scale) > 1e-2


def test_jacobian_matches_finite_differences() -> None:
    run, rec = oscillation(truth=truth(noiseless=True), duration_s=30.0)
    m = prepare_motion(rec.t_s, rec.table_rad_unwrapped(), run.axis_vectors, run.mount).take(
        slice(1500, 1700)
    )
    spec = ModelSpec(TERM_ORDER)
    th = _theta_true(run, spec)
    _, J = predict(th, m, spec, run.g_local_m_s2, np.zeros(3), jacobian=True)
    assert J is not None
    steps = {"bias": 1e-3, "K": 1e-4, "r": 1e-5, "q": 1e-5, "k2": 1e-5, "tilt": 1e-6, "delay": 1e-6}
    for k in range(spec.n_params):
        h = steps[spec.names[k].split("_")[0]]
        up, dn = th.copy(), th.copy()
        up[k] += h
        dn[k] -= h
        fd = (
            predict(up, m, spec, run.g_local_m_s2, np.zeros(3))[0]
            - predict(dn, m, spec, run.g_local_m_s2, np.zeros(3))[0]
        ) / (2 * h)
        np.testing.assert_allclose(
            J[:, :, k], fd, rtol=1e-6, atol=1e-7 * np.abs(fd).max() + 1e-14, err_msg=spec.names[k]
        )


def test_window_and_spec_rules() -> None:
    assert window_samples(100.0) == 7
    assert window_samples(1000.0) == 71
    assert ModelSpec(("proof_mass_offsets", "lever_arm")).terms == ("proof_mass_offsets",)
    assert ModelSpec(("time_skew", "lever_arm")).names[-4:] == ["r_x", "r_y", "r_z", "delay_s"]
    with pytest.raises(ValueError, match="unknown dynamic model term"):
        ModelSpec(("gyro_scale",))


def test_bad_motion_rejected() -> None:
    t = np.concatenate([[0.0], np.cumsum(np.tile([0.01, 0.0112], 10))])  # 12 % jitter, no gap
    with pytest.raises(ValueError, match="uniform"):
        prepare_motion(t, np.zeros((21, 1)), [[0, 0, 1]], np.eye(3))
    t = np.array([0.0, 0.01, 0.02, 0.05, 0.06, 0.07, 0.08, 0.09])  # a gap leaves two short stretches
    with pytest.raises(ValueError, match="no stretch"):
        prepare_motion(t, np.zeros((8, 1)), [[0, 0, 1]], np.eye(3))
    with pytest.raises(ValueError, match="samples"):
        prepare_motion(t[:3], np.zeros((3, 1)), [[0, 0, 1]], np.eye(3))


def test_motion_formed_in_chunks_is_the_motion_formed_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """Attitude, rate and acceleration are per-sample: the chunk size may not change a bit of G, B,
    their derivatives, the corner mask or the peak rate (which may lie in any chunk)."""
    from bench.estimation import motion_data

    run, rec = rate()
    q = rec.table_rad_unwrapped()
    monkeypatch.setattr(motion_data, "KINEMATICS_CHUNK", rec.t_s.size)
    whole = prepare_motion(rec.t_s, q, run.axis_vectors, run.mount)
    monkeypatch.setattr(motion_data, "KINEMATICS_CHUNK", 7)
    chunked = prepare_motion(rec.t_s, q, run.axis_vectors, run.mount)
    for name in ("G", "G_dot", "G_ddot", "B", "B_dot", "B_ddot", "valid"):
        np.testing.assert_array_equal(getattr(chunked, name), getattr(whole, name), err_msg=name)
    assert chunked.peak_rate_rad_s == whole.peak_rate_rad_s
    assert whole.peak_rate_rad_s == pytest.approx(np.radians(200.0), rel=1e-3)  # the rate table's top rate


def test_prediction_in_chunks_is_the_prediction_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """predict, specific_force and the sensor rates are per-sample: a chunk size that does not
    divide the recording (7) gives every bit of the whole-recording products, skew included."""
    from bench.diagnosis.library_motion import sensor_rates
    from bench.estimation import dynamic_model, motion_data

    run, rec = rate()
    m = prepare_motion(rec.t_s, rec.table_rad_unwrapped(), run.axis_vectors, run.mount)
    spec = ModelSpec(TERM_ORDER)
    th = _theta_true(run, spec)
    g = run.g_local_m_s2
    monkeypatch.setattr(motion_data, "PREDICT_CHUNK", m.n)
    raw_whole, _ = predict(th, m, spec, g, R_TRUE_M)
    f_whole = dynamic_model.specific_force(th, m, spec, g, R_TRUE_M)
    w_whole, dw_whole = sensor_rates(m)
    monkeypatch.setattr(motion_data, "PREDICT_CHUNK", 7)
    assert m.n % 7 != 0 and len(motion_data.sample_chunks(m.n)) == -(-m.n // 7)
    raw, _ = predict(th, m, spec, g, R_TRUE_M)
    np.testing.assert_array_equal(raw, raw_whole)
    np.testing.assert_array_equal(dynamic_model.specific_force(th, m, spec, g, R_TRUE_M), f_whole)
    w, dw = sensor_rates(m)
    np.testing.assert_array_equal(w, w_whole)
    np.testing.assert_array_equal(dw, dw_whole)
    # the chunked prediction is the model's: the first sample's raw output by hand
    d = DELAY_TRUE_S
    gb = g * np.array([np.sin(th[-2]), -np.cos(th[-2]) * np.sin(th[-3]), np.cos(th[-2]) * np.cos(th[-3])])
    Ge = m.G[0] - d * m.G_dot[0] + 0.5 * d * d * m.G_ddot[0]
    Be = m.B[0] - d * m.B_dot[0] + 0.5 * d * d * m.B_ddot[0]
    Q = th[spec.index("proof_mass_offsets")].reshape(3, 3)
    f0 = Ge @ gb + np.array([Be[i] @ Q[i] for i in range(3)])
    K = th[3:12].reshape(3, 3)
    k2 = th[spec.index("nonlinearity_quadratic")]
    expect = th[:3] + K @ f0 + np.diag(K) * k2 * f0**2 / 9.80665
    np.testing.assert_allclose(raw[0], expect, rtol=1e-12, atol=1e-12)
