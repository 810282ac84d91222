"""The wander test of library terms in time or temperature (``bench.diagnosis.wander_modes``).

Synthetic static evidence (an ideal triad at 18 directions, white noise, ``_evidence`` of
``test_diagnosis_library``): the classification of terms, the pose-modulated statistic
against its closed form under white noise, a wander's trend that no pose-modulated term may
claim, and a pose-modulated term that keeps its evidence.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.diagnosis.effects import first_order_design
from bench.diagnosis.effects.base import channel_column
from bench.diagnosis.evidence import G0_M_S2
from bench.diagnosis.likelihood import NoiseParams, gls, window_covariance
from bench.diagnosis.thresholds import THRESHOLDS
from bench.diagnosis.wander_modes import follows_time, modulated_lr, pose_modulated
from tests.bench.diagnosis.test_diagnosis_library import SIGMA, _evidence


@pytest.mark.parametrize(
    ("term", "time", "pose"),
    [
        ("f_z*t", True, True),
        ("abs(f_y)*t", True, True),
        ("f_x*temp^2", True, True),
        ("t^2", True, False),
        ("temp*t", True, False),
        ("f_x^2*f_z", False, True),
        ("abs(f_x)", False, True),
    ],
)
def test_terms_are_classified_by_their_factors(term: str, time: bool, pose: bool) -> None:
    assert follows_time(term) is time and pose_modulated(term) is pose


def _white(ev_m: int) -> NoiseParams:
    return NoiseParams(tau2=np.zeros(3))


def test_modulated_statistic_is_the_closed_form_under_white_noise() -> None:
    """With C = σ² I: LR_mod = (a⊥ᵀ y)² / (σ² a⊥ᵀ a⊥), a⊥ the term's column outside [X, s on its channel]."""
    ev = _evidence(np.random.default_rng(21))
    C = window_covariance(ev.V, ev.mid_s, _white(ev.m))
    X = first_order_design(ev.f_m_s2)
    a = channel_column(ev, 0, ev.f_m_s2[:, 2] / G0_M_S2 * ev.mid_s)
    lr, b = modulated_lr(ev, X, a, 0, C, THRESHOLDS.relative_leverage_min)
    s = (ev.mid_s - ev.mid_s.mean()) / np.ptp(ev.mid_s)
    A = np.hstack([X, channel_column(ev, 0, s)])
    Q, _ = np.linalg.qr(A)
    ap = a[:, 0] - Q @ (Q.T @ a[:, 0])
    y = ev.y.reshape(-1)
    assert b == 1
    assert lr == pytest.approx(float(ap @ y) ** 2 / (SIGMA**2 * float(ap @ ap)), rel=1e-6)


def test_a_wanders_trend_gives_a_pose_modulated_term_nothing() -> None:
    """az carries a trend in time (a wander's slow part, 60 sigma over the run): a term in |f_y|·t
    fits it under white noise, but beside the trend column its statistic is χ²_1 noise."""
    rng = np.random.default_rng(22)
    ev0 = _evidence(rng)
    extra = np.zeros_like(ev0.y)
    extra[:, 2] = 60 * SIGMA * (ev0.mid_s / np.ptp(ev0.mid_s) - 0.5)
    ev = _evidence(np.random.default_rng(22), extra)
    C = window_covariance(ev.V, ev.mid_s, _white(ev.m))
    X = first_order_design(ev.f_m_s2)
    y = ev.y.reshape(-1)
    a = channel_column(ev, 2, np.abs(ev.f_m_s2[:, 1]) / G0_M_S2 * ev.mid_s)
    plain = gls(X, y, C).chi2 - gls(np.hstack([X, a]), y, C).chi2
    lr, _ = modulated_lr(ev, X, a, 2, C, THRESHOLDS.relative_leverage_min)
    assert plain > 100.0
    assert lr < 15.0  # χ²_1 beyond p = 1e-4


def test_a_pose_modulated_term_keeps_its_evidence_beside_the_trend() -> None:
    """f_z·t on ax (a mount creeping, 2e-7 V per g·s): its statistic beside the trend column is
    the share of its signature outside s, which the closed form gives, and far above any gate."""
    ev0 = _evidence(np.random.default_rng(23))
    c = 2e-7
    extra = np.zeros_like(ev0.y)
    extra[:, 0] = c * ev0.f_m_s2[:, 2] / G0_M_S2 * ev0.mid_s
    ev = _evidence(np.random.default_rng(23), extra)
    C = window_covariance(ev.V, ev.mid_s, _white(ev.m))
    X = first_order_design(ev.f_m_s2)
    a = channel_column(ev, 0, ev.f_m_s2[:, 2] / G0_M_S2 * ev.mid_s)
    lr, _ = modulated_lr(ev, X, a, 0, C, THRESHOLDS.relative_leverage_min)
    s = (ev.mid_s - ev.mid_s.mean()) / np.ptp(ev.mid_s)
    Q, _ = np.linalg.qr(np.hstack([X, channel_column(ev, 0, s)]))
    ap = a[:, 0] - Q @ (Q.T @ a[:, 0])
    expected = c**2 * float(ap @ ap) / SIGMA**2  # the noncentrality: E[LR_mod] = 1 + this
    assert expected > 40.0
    assert abs(lr - (1.0 + expected)) < 4.0 * np.sqrt(2.0 + 4.0 * expected)


def test_the_trend_column_is_left_out_when_the_model_has_it() -> None:
    """With bias_drift's column (t on ax) in X, s on ax adds nothing: b = 0, no rank error."""
    ev = _evidence(np.random.default_rng(24))
    C = window_covariance(ev.V, ev.mid_s, _white(ev.m))
    X = np.hstack([first_order_design(ev.f_m_s2), channel_column(ev, 0, ev.mid_s)])
    a = channel_column(ev, 0, ev.f_m_s2[:, 2] / G0_M_S2 * ev.mid_s)
    lr, b = modulated_lr(ev, X, a, 0, C, THRESHOLDS.relative_leverage_min)
    Q, _ = np.linalg.qr(X)
    ap = a[:, 0] - Q @ (Q.T @ a[:, 0])
    assert b == 0
    assert lr == pytest.approx(float(ap @ ev.y.reshape(-1)) ** 2 / (SIGMA**2 * float(ap @ ap)), rel=1e-6)
