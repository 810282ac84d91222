"""Diagnosis of static evidence: likelihood pieces against closed forms, selection on injected truth."""

from __future__ import annotations

import numpy as np
import pytest

from bench.diagnosis import StaticEvidence, diagnose
from bench.diagnosis.effects import CATALOGUE, first_order_design
from bench.diagnosis.likelihood import NoiseParams, covariance, gls

CONTRACT_IDS = [
    "lever_arm",
    "proof_mass_offsets",
    "nonlinearity_quadratic",
    "scale_asymmetry",
    "cross_coupling",
    "temperature_bias",
    "bias_drift",
    "time_skew",
    "table_tilt",
    "pose_error",
    "encoder_offset",
    "sensor_lowpass",
    "settling",
]


def test_catalogue_is_the_contract() -> None:
    assert [e.id for e in CATALOGUE] == CONTRACT_IDS
    names = {e.id: [p.name for p in e.parameters] for e in CATALOGUE}
    assert names["nonlinearity_quadratic"] == ["k2_per_g"] and names["table_tilt"] == ["tilt_rad"]
    assert names["pose_error"] == ["angles_rad"] and names["encoder_offset"] == ["offset_deg"]
    assert all(e.explanation.strip() for e in CATALOGUE)


def test_gls_equals_ols_for_white_noise_and_loglik_closed_form() -> None:
    rng = np.random.default_rng(0)
    X = rng.normal(size=(30, 4))
    z = X @ np.array([1.0, -2.0, 0.5, 3.0]) + rng.normal(0, 0.1, 30)
    fit = gls(X, z, 0.01 * np.eye(30))
    ols = np.linalg.lstsq(X, z, rcond=None)[0]
    np.testing.assert_allclose(fit.theta, ols, rtol=1e-10)
    r = z - X @ ols
    ll = -0.5 * (r @ r / 0.01 + 30 * np.log(0.01) + 30 * np.log(2 * np.pi))
    assert fit.loglik_ml == pytest.approx(ll, rel=1e-10)
    np.testing.assert_allclose(fit.cov, 0.01 * np.linalg.inv(X.T @ X), rtol=1e-10)


def test_covariance_blocks_and_correlation() -> None:
    V = np.stack([np.eye(3) * (w + 1) for w in range(3)])
    C = covariance(V, np.array([0.0, 10.0, 30.0]), NoiseParams(tau2=np.array([1.0, 0, 0]), corr_time_s=10.0))
    assert C[0, 0] == pytest.approx(2.0) and C[1, 1] == pytest.approx(1.0)
    assert C[0, 3] == pytest.approx(np.exp(-1.0)) and C[0, 6] == pytest.approx(np.exp(-3.0))
    assert C[1, 4] == 0.0


def _synthetic(rng: np.random.Generator, k2_z: float = 0.0, sigma: float = 1e-5) -> StaticEvidence:
    """Window means of an ideal triad at 18 directions, white noise, an optional z nonlinearity."""
    g = 9.81
    dirs = np.array(
        [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
         [1, 1, 0], [1, 0, 1], [0, 1, 1], [-1, 1, 0], [-1, 0, -1], [0, -1, 1],
         [1, 1, 1], [-1, -1, 1], [1, -1, -1], [-1, 1, -1], [1, 0, -1], [0, 1, -1]],
        dtype=float,
    )  # fmt: skip
    f = g * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    K = np.diag([0.0177, 0.0175, 0.0178]) + 1e-5
    b = np.array([1.5, 1.49, 1.51])
    y = b + f @ K.T
    y[:, 2] += K[2, 2] * k2_z * f[:, 2] ** 2 / 9.80665
    y += rng.normal(0, sigma, y.shape)
    m = f.shape[0]
    V = np.broadcast_to(np.eye(3) * sigma**2, (m, 3, 3)).copy()
    return StaticEvidence(
        y=y, V=V, f_m_s2=f, mid_s=np.arange(m) * 40.0, labels=tuple(f"w{i}" for i in range(m)), g_local_m_s2=g
    )


def test_clean_synthetic_has_no_finding() -> None:
    d = diagnose(_synthetic(np.random.default_rng(1)))
    assert d.findings == ()
    assert d.final.chi2_dof < 2.0
    motion = {"lever_arm", "proof_mass_offsets", "time_skew", "sensor_lowpass", "settling"}
    assert set(d.unobservable) >= motion


def test_injected_nonlinearity_is_recovered_within_its_sigma() -> None:
    k2 = 2e-3
    d = diagnose(_synthetic(np.random.default_rng(2), k2_z=k2))
    assert [f.effect for f in d.findings] == ["nonlinearity_quadratic"]
    f = d.findings[0]
    est, sig = f.parameters["k2_per_g"][2], f.sigma["k2_per_g"][2]
    assert abs(est - k2) < 3 * sig and sig < k2 / 5
    assert f.parameters["k2_per_g"][:2] == [0.0, 0.0]
    assert f.delta_bic < 0 and d.final.bic < d.baseline.bic
    assert d.baseline.chi2_dof > 5 and d.final.chi2_dof < 2
    assert d.channel_ratio[2] > 5 * max(d.channel_ratio[:2])
    assert "az" in d.where


def test_too_few_windows_is_refused() -> None:
    ev = _synthetic(np.random.default_rng(3))
    small = StaticEvidence(
        y=ev.y[:4],
        V=ev.V[:4],
        f_m_s2=ev.f_m_s2[:4],
        mid_s=ev.mid_s[:4],
        labels=ev.labels[:4],
        g_local_m_s2=9.81,
    )
    with pytest.raises(ValueError, match="at least 5 static windows"):
        diagnose(small)


def test_evidence_rejects_non_finite_with_window_name() -> None:
    ev = _synthetic(np.random.default_rng(4))
    y = ev.y.copy()
    y[3, 1] = np.nan
    with pytest.raises(ValueError, match="'w3'"):
        StaticEvidence(y=y, V=ev.V, f_m_s2=ev.f_m_s2, mid_s=ev.mid_s, labels=ev.labels, g_local_m_s2=9.81)


def test_first_order_design_layout() -> None:
    f = np.arange(6.0).reshape(2, 3)
    X = first_order_design(f)
    assert X.shape == (6, 12)
    np.testing.assert_array_equal(X[5, [2, 9, 10, 11]], [1.0, 3.0, 4.0, 5.0])
