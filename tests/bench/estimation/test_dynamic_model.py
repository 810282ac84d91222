"""The dynamic measurement model against the simulator's independent physics, and its Jacobian."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import savgol_filter

from bench.estimation.dynamic_model import TERM_ORDER, ModelSpec, initial_theta, predict
from bench.estimation.motion_data import BASIS_BYTES, RATES_BYTES, MotionData, prepare_motion, window_samples
from bench.kinematics import angular_acceleration, angular_velocity, inner_attitude
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


def _whole_recording_regressors(m: MotionData) -> dict[str, np.ndarray]:
    """G, B for every sample at once, then their Savitzky–Golay derivatives run by run over whole
    runs (zero outside them): the formulation that holds six (n, 3, 3) arrays."""
    R = inner_attitude(m.axis_vectors, m.angles_rad)
    G = np.einsum("ji,njk->nik", m.mount, np.transpose(R, (0, 2, 1)))
    om = angular_velocity(m.axis_vectors, m.angles_rad, m.rates_rad_s)
    dom = angular_acceleration(m.axis_vectors, m.angles_rad, m.rates_rad_s, m.accels_rad_s2)

    def cross_matrix(v: np.ndarray) -> np.ndarray:  # column j is v × e_j
        return np.stack([np.cross(v, e) for e in np.eye(3)], axis=-1)

    W = cross_matrix(om)
    B = G @ (cross_matrix(dom) + W @ W) @ R

    def sg(x: np.ndarray, deriv: int) -> np.ndarray:
        out = np.zeros_like(x)
        for a, b in m.runs:
            out[a:b] = savgol_filter(x[a:b], m.window, 3, deriv=deriv, delta=m.step_s, axis=0, mode="interp")
        return out

    return {"G": G, "G_dot": sg(G, 1), "B": B, "B_dot": sg(B, 1), "G_ddot": sg(G, 2), "B_ddot": sg(B, 2)}


@pytest.mark.parametrize("rate_hz", [100.0, 1000.0])
def test_regressors_taken_at_any_samples_are_the_whole_recording_ones(
    monkeypatch: pytest.MonkeyPatch, rate_hz: float
) -> None:
    """A rate-table recording (corners at every ramp) with dropped blocks (two runs, a stretch
    shorter than the window): G, B and their derivatives taken at any samples — all, the valid
    ones, a sparse subsample, unsorted with repeats, at and beside the runs' ends, outside the
    runs — in pieces of any size are every bit of the whole-recording computation's."""
    from bench.estimation import motion_data

    run, rec = rate(rate_hz=rate_hz, rates_deg_s=(0.0, 120.0, -200.0), dwell_s=3.0)
    n0 = rec.n_samples
    keep = np.ones(n0, dtype=bool)
    keep[n0 // 5 : n0 // 5 + 40] = False
    keep[n0 // 3 : n0 // 3 + 3] = False
    keep[n0 // 3 + 6 : n0 // 3 + 12] = False  # leaves a 3-sample stretch
    m = prepare_motion(
        rec.t_s[keep], rec.table_rad_unwrapped()[keep], run.axis_vectors, run.mount, keep_bytes=0
    )
    assert m.kept is None and (
        len(m.runs) == 3 and m.runs[1][1] < m.runs[2][0] and (~m.valid[m.runs[0][0] :]).sum() > 3 * m.window
    )
    ref = _whole_recording_regressors(m)
    h = m.window // 2
    ends = [x for a, b in m.runs for d in (0, 1, h - 1, h, h + 1) for x in (a + d, b - 1 - d)]
    cases = {
        "all": slice(0, m.n),
        "valid": np.flatnonzero(m.valid),
        "sparse": np.flatnonzero(m.valid)[::37],
        "unsorted": np.random.default_rng(0).integers(0, m.n, 400),
        "ends": np.array(ends),
        "outside": np.arange(m.runs[1][1], m.runs[2][0]),
    }
    for chunk in (1 << 15, 7 * m.window, 7):  # 7: a piece per sample (a window adds up to m.window)
        monkeypatch.setattr(motion_data, "KINEMATICS_CHUNK", chunk)
        for case, idx in cases.items():
            if chunk == 7 and case in ("all", "valid") and m.window > 7:
                continue  # a piece per sample of the whole recording: seconds of work for nothing new
            ms = m.take(idx)
            for name, whole in ref.items():
                np.testing.assert_array_equal(getattr(ms, name), whole[idx], err_msg=f"{chunk} {case} {name}")
            np.testing.assert_array_equal(ms.valid, m.valid[idx])
    assert np.all(ref["G_dot"][cases["outside"]] == 0.0) and np.any(ref["G_dot"][cases["valid"]] != 0.0)
    monkeypatch.setattr(motion_data, "KINEMATICS_CHUNK", 1 << 15)
    kept = prepare_motion(rec.t_s[keep], rec.table_rad_unwrapped()[keep], run.axis_vectors, run.mount)
    assert kept.kept is not None  # within KEEP_BYTES: formed once, taken from there
    for case, idx in cases.items():
        ms = kept.take(idx)
        for name, whole in ref.items():
            np.testing.assert_array_equal(getattr(ms, name), whole[idx], err_msg=f"kept {case} {name}")
    part = m.runs[1][0] + 2  # budgets that end just inside the second run
    for budget, n_basis, n_rates in (
        (BASIS_BYTES * part + BASIS_BYTES - 1, part, 0),  # G, B of the first samples only
        (BASIS_BYTES * m.n + RATES_BYTES * part + RATES_BYTES - 1, m.n, part),  # all G, B; some rates
    ):
        partly = prepare_motion(
            rec.t_s[keep], rec.table_rad_unwrapped()[keep], run.axis_vectors, run.mount, keep_bytes=budget
        )
        assert partly.kept is not None and (partly.kept.n_basis, partly.kept.n_rates) == (n_basis, n_rates)
        for case, idx in cases.items():
            for rates in (True, False):
                ms = partly.take(idx, rates=rates)
                for name, whole in ref.items():
                    if rates or name in ("G", "B"):
                        got = getattr(ms, name)
                        np.testing.assert_array_equal(got, whole[idx], err_msg=f"{budget} {case} {name}")
                np.testing.assert_array_equal(ms.t_s, m.t_s[idx])
                np.testing.assert_array_equal(ms.valid, m.valid[idx])
    with pytest.raises(ValueError, match="G_dot was not formed"):
        _ = partly.take(cases["sparse"], rates=False).G_dot
    whole_peak = m.peak_rate_rad_s
    monkeypatch.setattr(motion_data, "KINEMATICS_CHUNK", 7)
    chunked = prepare_motion(
        rec.t_s[keep], rec.table_rad_unwrapped()[keep], run.axis_vectors, run.mount, keep_bytes=0
    )
    assert chunked.peak_rate_rad_s == whole_peak
    assert whole_peak == pytest.approx(np.radians(200.0), rel=1e-3)  # the rate table's top rate


def test_prediction_in_chunks_is_the_prediction_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """predict, specific_force and the sensor rates are per-sample: a chunk size that does not
    divide the recording (997; each chunk takes its own regressors from the motion) gives every
    bit of the whole-recording products, skew included."""
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
    monkeypatch.setattr(motion_data, "PREDICT_CHUNK", 997)
    assert m.n % 997 != 0 and len(motion_data.sample_chunks(m.n)) == -(-m.n // 997)
    raw, _ = predict(th, m, spec, g, R_TRUE_M)
    np.testing.assert_array_equal(raw, raw_whole)
    np.testing.assert_array_equal(dynamic_model.specific_force(th, m, spec, g, R_TRUE_M), f_whole)
    w, dw = sensor_rates(m)
    np.testing.assert_array_equal(w, w_whole)
    np.testing.assert_array_equal(dw, dw_whole)
    # the chunked prediction is the model's: the first sample's raw output by hand
    d = DELAY_TRUE_S
    gb = g * np.array([np.sin(th[-2]), -np.cos(th[-2]) * np.sin(th[-3]), np.cos(th[-2]) * np.cos(th[-3])])
    m0 = m.take(slice(0, 1))
    Ge = m0.G[0] - d * m0.G_dot[0] + 0.5 * d * d * m0.G_ddot[0]
    Be = m0.B[0] - d * m0.B_dot[0] + 0.5 * d * d * m0.B_ddot[0]
    Q = th[spec.index("proof_mass_offsets")].reshape(3, 3)
    f0 = Ge @ gb + np.array([Be[i] @ Q[i] for i in range(3)])
    K = th[3:12].reshape(3, 3)
    k2 = th[spec.index("nonlinearity_quadratic")]
    expect = th[:3] + K @ f0 + np.diag(K) * k2 * f0**2 / 9.80665
    np.testing.assert_allclose(raw[0], expect, rtol=1e-12, atol=1e-12)
