"""Static fit on long sessions: a wander correlated between windows reaches the sigmas.

Sessions simulated at the level of the window means (``benchmarks.study_long_recording``):
hand-placement errors, a Gauss-Markov wander and a daily temperature swing. The truth is
known, so the z-scores and the agreement of two disjoint halves are checked against it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench.estimation.static_fit import fit_static
from bench.estimation.static_wander import correlation_time_grid
from benchmarks.study_long_recording import LongSession, simulate, study


def test_wander_correlated_over_many_windows_widens_the_bias_sigma() -> None:
    """A wander with a correlation time of a tenth of the session leaves about
    span / (2 T_c) = 5 independent values of it: sigma(b) ~ tau / sqrt(5) ~ 0.45 tau, whatever
    the number of windows. Independent window errors would claim about tau / sqrt(m) = 0.07 tau
    (a little more where a channel's Paule-Mandel excess also takes the placement scatter):
    below the correlated model's lower bound either way."""
    cfg = LongSession(m=200, hours=2.0, wander_m_s2=2e-3, wander_tau_s=720.0, tc_m_s2_per_c=0.0)
    worst = []
    for seed in (3, 4):
        r = simulate(cfg, seed=seed)
        fit = fit_static(r["f"], r["y"], r["V"], mid_s=r["mid_s"])
        ind = fit_static(r["f"], r["y"], r["V"])
        tau_ch = cfg.wander_m_s2 * np.diag(r["K"])  # the wander in channel units
        assert "slow wander" in fit.noise_model
        assert fit.bias_reference == "long_run"
        assert np.all(fit.bias_sigma > 0.25 * tau_ch) and np.all(fit.bias_sigma < 0.9 * tau_ch)
        assert np.all(ind.bias_sigma < 0.2 * tau_ch)  # what independent errors claim
        worst.append(np.max(np.abs(fit.bias - r["b"]) / fit.bias_sigma))
    assert max(worst) < 4.0


def test_short_clean_session_keeps_the_independent_model() -> None:
    cfg = LongSession(m=24, hours=0.2, wander_m_s2=1e-6, tc_m_s2_per_c=0.0, pose_rad=1e-5)
    r = simulate(cfg, seed=5)
    fit = fit_static(r["f"], r["y"], r["V"], mid_s=r["mid_s"])
    ref = fit_static(r["f"], r["y"], r["V"])
    assert "slow wander" not in fit.noise_model
    assert fit.bias_reference == "run_mean"
    np.testing.assert_allclose(fit.cov, ref.cov, rtol=1e-12)


def test_window_times_are_checked() -> None:
    r = simulate(LongSession(m=20, hours=0.5), seed=1)
    with pytest.raises(ValueError, match="window times"):
        fit_static(r["f"], r["y"], r["V"], mid_s=r["mid_s"][:5])


def test_correlation_time_grid_reaches_down_to_the_window_spacing() -> None:
    t = np.arange(1000) * 60.0  # 1000 windows a minute apart
    grid = correlation_time_grid(t)
    span = t[-1]
    assert grid[-3:] == pytest.approx([0.3 * span, span, 3 * span])
    assert min(grid) >= 120.0 and min(grid) < 4 * 120.0
    assert correlation_time_grid(np.arange(12) * 37.0) == pytest.approx([0.3 * 407, 407, 3 * 407])


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_long_sessions_z_spread_and_halves_agree() -> None:
    """8 sessions of 240 windows over 20 h (wander 1 h, ±5 °C daily, 0.003 rad placement):
    z against the truth (96 values) spreads 0.8-1.25, and the two halves of each session
    agree within 3.5 sigma (measured on 6 sessions of 300: spread 0.94, halves 2.95 at most)."""
    res = study(8, replace(LongSession(), m=240))
    assert 0.8 <= res["z_spread_correlated"] <= 1.25, res
    assert res["halves_max"] < 3.5 and res["halves_spread"] <= 1.25, res
