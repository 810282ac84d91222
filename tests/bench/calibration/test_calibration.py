"""bench.calibration: recording -> calibration, against independent truths."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.calibration import calibrate_recording
from bench.calibration.kind import FitKind
from bench.recording import Recording, Segment, Sidecar, read_recording
from tests.support.static_sim import G_LOCAL, random_truth

CONTRACT_KEYS = {
    "unit", "channel_unit", "procedure", "bias", "bias_sigma", "scale_matrix", "scale_matrix_sigma",
    "terms", "extra", "residual_rms", "g_check",
    # added (fields may be added): redundancy and what was not used
    "dof", "zero_redundancy", "unused_windows", "warnings",
    # which bias bias_sigma describes
    "bias_reference",
}  # fmt: skip


def test_independent_example_recovered_within_three_sigma(independent_dir) -> None:
    ex = independent_dir
    rec = read_recording(ex / "example_static12.csv")
    truth = json.loads((ex / "example_static12.truth.json").read_text())
    res = calibrate_recording(rec)
    zb = (res.bias - np.array(truth["bias_v"])) / res.bias_sigma
    zk = (res.K - np.array(truth["K_v_per_m_s2"])) / res.K_sigma
    assert np.all(np.abs(zb) < 3.0), zb
    assert np.all(np.abs(zk) < 3.0), zk
    out = res.to_contract()
    assert set(out) == CONTRACT_KEYS
    assert out["terms"] == ["bias", "scale_matrix"] and out["extra"] == {}
    assert set(out["g_check"]) == {"after"}  # volts: no nominal scale, no 'before'
    # after correction |g| scatters at the window-mean noise level: 2 mg/√2900 ≈ 0.4 mm/s² per axis
    assert abs(out["g_check"]["after"]["mean_error_m_s2"]) < 3e-4
    assert out["g_check"]["after"]["std_m_s2"] < 1e-3
    assert len(res.windows) == 12 and res.dof == 24
    json.dumps(out)  # plain JSON types only


def _hand_recording(
    f: np.ndarray, b: np.ndarray, K: np.ndarray, rng, *, nominal_up=None, unit="V"
) -> Recording:
    fs, n_dwell, n_gap = 100.0, 800, 100
    rows, segs, t0 = [], [], 0
    for w, fw in enumerate(f):
        rows.append(np.tile(b + K @ fw, (n_gap, 1)) + rng.normal(0, 5e-3, (n_gap, 3)) * K[0, 0] * 50)
        start = t0 + n_gap
        rows.append(b + fw @ K.T + rng.normal(0, 2e-3 * 9.8, (n_dwell, 3)) @ K.T)
        segs.append(
            Segment(
                (start + 5) / fs,
                (start + n_dwell - 5) / fs,
                f"p{w:02d}",
                None if nominal_up is None else nominal_up[w],
            )
        )
        t0 = start + n_dwell
    accel = np.vstack(rows)
    side = Sidecar(
        unit_serial="SN-H", channel_unit=unit, sample_rate_hz=fs, g_local_m_s2=G_LOCAL, segments=tuple(segs)
    )
    return Recording(sidecar=side, t_s=np.arange(accel.shape[0]) / fs, accel_raw=accel, source="hand.csv")


def test_six_position_hand_calibration_uses_nominal_up() -> None:
    rng = np.random.default_rng(3)
    b, K = random_truth(rng)
    ups = ["+x", "-x", "+y", "-y", "+z", "-z"]
    f = G_LOCAL * np.vstack([np.eye(3)[i // 2] * (1 if i % 2 == 0 else -1) for i in range(6)])
    res = calibrate_recording(_hand_recording(f, b, K, rng, nominal_up=ups))
    assert res.kind is FitKind.STATIC and res.dof == 6
    z = (np.r_[res.bias, res.K.ravel()] - np.r_[b, K.ravel()]) / np.r_[res.bias_sigma, res.K_sigma.ravel()]
    assert np.all(np.abs(z) < 4.0), z


def test_recording_without_orientations_uses_the_scalar_fit() -> None:
    rng = np.random.default_rng(4)
    b, K = random_truth(rng)
    f = Rotation.random(16, random_state=9).inv().apply([0.0, 0.0, G_LOCAL])
    res = calibrate_recording(
        _hand_recording(f, b, K, rng), nominal_scale=0.0176, nominal_bias=np.full(3, 1.5)
    )
    assert res.kind is FitKind.ORIENTATION_FREE
    assert res.to_contract()["terms"] == ["bias", "scale_matrix_lower_triangular"]
    assert np.all(np.abs((res.bias - b) / res.bias_sigma) < 4.0)
    np.testing.assert_allclose(res.K @ res.K.T, K @ K.T, rtol=0, atol=2e-3 * np.max(K @ K.T))
    assert set(res.to_contract()["g_check"]) == {"before", "after"}
    assert res.g_after.std_m_s2 < 0.1 * res.g_before.std_m_s2  # type: ignore[union-attr]


def test_degenerate_and_short_recordings_are_refused_with_the_file_named() -> None:
    rng = np.random.default_rng(5)
    b, K = random_truth(rng)
    f = G_LOCAL * np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0.6, 0.8, 0]], dtype=float)
    ups = ["+x", "+y", "-x", "-y", "+x"]
    with pytest.raises(ValueError, match=r"^hand.csv: .*K\[:,2\] \(response to f_z\) cannot be determined"):
        calibrate_recording(_hand_recording(f, b, K, rng, nominal_up=ups))
    f8 = Rotation.random(8, random_state=2).inv().apply([0.0, 0.0, G_LOCAL])
    with pytest.raises(ValueError, match=r"^hand.csv: .*at least 9 static windows"):
        calibrate_recording(_hand_recording(f8, b, K, rng))
