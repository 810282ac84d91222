"""The real data sets in tests/data/real, calibrated (numbers recorded in docs/real-datasets.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.calibration import calibrate_recording
from bench.calibration.kind import FitKind
from bench.convert import read_imu_tk, read_imucal_annotated, read_imucal_session
from bench.estimation.g_check import g_check


@pytest.fixture(scope="module")
def imucal_dir(real_dir):
    return real_dir / "imucal-ferraris"


def test_imucal_annotated_session_against_imucal_output(imucal_dir) -> None:
    """Same six windows: our |g| scatter after correction is imucal's (example_cal.json), no worse."""
    rec = read_imucal_annotated(imucal_dir / "annotated_session.csv", 204.8)
    res = calibrate_recording(rec)
    assert res.kind is FitKind.STATIC and [w.label for w in res.windows] == [
        "x_p",
        "x_a",
        "y_p",
        "y_a",
        "z_p",
        "z_a",
    ]
    cal = json.loads((imucal_dir / "example_cal.json").read_text())
    KR = np.array(cal["K_a"]) @ np.array(cal["R_a"])  # imucal: a = R⁻¹ K⁻¹ (u − b)  ⇔  u = b + (K R) a
    b_imucal = np.array(cal["b_a"])
    y = np.array([w.mean_raw for w in res.windows])
    g = rec.sidecar.g_local_m_s2
    # Like for like: Ferraris' closed form (imucal's equations 19-23, grav = 9.81) on our window
    # means with our g reproduces the golden file, so both use the same samples and the same g.
    assert g == 9.81
    up, un = y[0::2].T, y[1::2].T  # columns x, y, z of the +g and −g poses
    np.testing.assert_allclose(np.diag(up + un) / 2, b_imucal, rtol=0, atol=1e-9)
    np.testing.assert_allclose((up - un) / (2 * g), KR, rtol=1e-12, atol=1e-12)
    # The same statistic on both: std (ddof = 1) over the six windows of |K⁻¹(ȳ − b)| − g.
    theirs = g_check(np.linalg.solve(KR, (y - b_imucal).T).T, g)
    assert theirs.std_m_s2 == pytest.approx(6.650e-4, rel=1e-3)
    assert res.g_after.std_m_s2 <= theirs.std_m_s2  # no worse than imucal: 3.91e-4 vs 6.65e-4
    # The two share the scale/misalignment; they differ in the bias (joint fit: the readings
    # along gravity, free of first-order pose error, carry the weight).
    np.testing.assert_allclose(np.linalg.inv(res.K), np.linalg.inv(KR), rtol=0, atol=1e-8)
    # What is left of our |g| scatter is the z pair's second-order pose term, worked out from
    # the off-axis residual alone: |f + δ×f| − g = g (√(1 + δ²) − 1), δ = |K⁻¹ r⊥| / g.
    err = res.g_after.error_m_s2
    assert np.all(np.abs(err[:4]) < 5e-5)
    delta = np.linalg.norm(np.linalg.solve(res.K, res.windows[4].residual)) / g
    np.testing.assert_allclose(err[4:], g * (np.sqrt(1 + delta**2) - 1), rtol=0.05)
    # what imucal does not report: the windows disagree with the model far beyond their noise
    # (off-axis residuals up to ~25 counts ≈ 0.12 m/s²: hand-placement pose errors)
    assert res.chi2 / res.dof > 1000
    worst = max(np.max(np.abs(w.residual)) for w in res.windows)
    assert 20 < worst < 30
    assert np.all(res.bias_sigma > 0.1) and np.all(res.bias_sigma < 1.0)  # counts: pose scatter included


def test_imucal_session_in_m_s2_has_before_and_after(imucal_dir) -> None:
    rec = read_imucal_session(
        imucal_dir / "example_ferraris_session.csv", imucal_dir / "example_ferraris_session_list.json", 102.4
    )
    res = calibrate_recording(rec)
    assert res.g_before is not None
    # README: |a| 9.23–10.48 m/s² before; imucal leaves 9.8096–9.8106 after
    assert res.g_before.std_m_s2 == pytest.approx(0.589, rel=0.01)
    assert res.g_after.std_m_s2 < 1e-4  # 3.8e-5 m/s²
    assert np.all(np.abs(res.g_after.error_m_s2) < 1e-3)
    assert res.residual_rms == pytest.approx(0.0173, rel=0.02)  # the labels' misfit


def test_xsens_scalar_calibration(real_dir) -> None:
    rec = read_imu_tk(
        real_dir / "imu_tk-xsens" / "xsens_mti_raw_counts.csv",
        channel_unit=None,
        g_local_m_s2=9.81744,
    )
    res = calibrate_recording(rec)
    assert res.kind is FitKind.ORIENTATION_FREE and len(res.windows) == 38
    # reference fit in the data set's README: RMS 0.98 mm/s², bias ≈ [33124, 33275, 32364] counts
    assert res.g_after.rms_m_s2 == pytest.approx(0.985e-3, rel=0.02)
    np.testing.assert_allclose(res.bias, [33124, 33275, 32364], atol=2.0)
    assert np.all(np.abs(res.bias - [33124, 33275, 32364]) < 5 * res.bias_sigma + 1.0)
    # 1 / scale ≈ [0.002413, 0.002427, 0.002412] m/s² per count
    np.testing.assert_allclose(1 / np.diag(res.K), [0.002413, 0.002427, 0.002412], rtol=3e-3)
