"""``thermal_lag``: the lag's recursion against closed forms, its reduction to
``temperature_bias`` at τ → 0, and Davies' bound on a process whose maximum is known."""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from bench.diagnosis.effects.sensor import TEMPERATURE
from bench.diagnosis.effects.thermal_lag import THERMAL_LAG, lagged_c, tau_grid_s, window_means_c
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.profiled import arc_length, davies_gate, effective_tries


def test_step_response_on_an_uneven_clock() -> None:
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.05, 0.5, 4000))
    temp = np.where(t >= 100.0, 2.0, -1.0)
    tau = 7.0
    out = lagged_c(t, temp, tau)
    # the step holds over the interval before its first sample: from the last sample before it
    s = t[t < 100.0][-1]
    after = t >= 100.0
    expect = 2.0 - 3.0 * np.exp(-(t[after] - s) / tau)
    assert np.allclose(out[after], expect, rtol=0, atol=1e-10)
    assert np.allclose(out[~after], -1.0, rtol=0, atol=1e-12)


def test_sinusoid_amplitude_and_phase_over_many_blocks() -> None:
    # 2000 s at 100 Hz with τ = 2 s: 1000 e-foldings, twenty blocks of the recursion
    t = np.arange(0.0, 2000.0, 0.01)
    w, tau = 2 * math.pi / 150.0, 2.0
    out = lagged_c(t, np.sin(w * t), tau)
    late = t > 100.0
    # steady state of τ·Ṫ_e = T − T_e; T held over the interval before each sample is the
    # continuous input half a sample early
    expect = np.sin(w * (t[late] + 0.005) - math.atan(w * tau)) / math.hypot(1.0, w * tau)
    assert np.max(np.abs(out[late] - expect)) < 1e-5


def _evidence(temp_run: np.ndarray, t: np.ndarray, bounds: np.ndarray) -> StaticEvidence:
    m = bounds.shape[0]
    temp = np.array([temp_run[a:b].mean() for a, b in bounds])
    f = np.tile([0.0, 0.0, 9.8], (m, 1))
    f[::2] *= -1.0
    return StaticEvidence(
        y=np.zeros((m, 3)), V=np.tile(np.eye(3) * 1e-8, (m, 1, 1)), f_m_s2=f,
        mid_s=np.array([t[(a + b - 1) // 2] for a, b in bounds]), labels=tuple(f"w{i}" for i in range(m)),
        g_local_m_s2=9.8, temp_c=temp, run_t_s=t, run_temp_c=temp_run, window_bounds=bounds,
    )  # fmt: skip


def test_no_lag_is_the_plain_temperature_column() -> None:
    t = np.arange(0.0, 600.0, 0.1)
    temp = 25.0 + 1.5 * np.sin(2 * math.pi * t / 150.0)
    bounds = np.array([[k * 500 + 100, k * 500 + 400] for k in range(12)])
    ev = _evidence(temp, t, bounds)
    assert ev.temp_c is not None
    assert np.allclose(window_means_c(ev, 0.0), ev.temp_c, rtol=0, atol=1e-12)
    K = np.diag([1.1, 0.9, 1.0])
    fam = THERMAL_LAG.candidates(ev)[1].family
    assert fam is not None
    plain = TEMPERATURE.candidates(ev)[1].columns(ev, K)
    assert np.allclose(fam.null_column(ev, K), plain, rtol=0, atol=1e-12)
    # a lag far shorter than the sample interval is the plain column too
    assert np.allclose(fam.column(ev, K, 1e-6), plain, rtol=0, atol=1e-9)
    # and a lag much longer than the cycle flattens it: the swing falls as 1/sqrt(1 + (ωτ)²)
    long = window_means_c(ev, 600.0)
    assert np.ptp(long) < 0.2 * np.ptp(ev.temp_c)
    grid = tau_grid_s(ev)
    assert grid[0] == 1.0 and abs(grid[-1] - t[-1]) < 1e-9


def test_davies_bound_is_the_rate_of_a_cosine_process() -> None:
    # Z(v) = ξ₁ cos v + ξ₂ sin v = R cos(v − φ) on [0, L]: unit variance, its normalised curve
    # has length L; Z² reaches R² (P(R² > u) = e^{−u/2}) when φ or φ + π falls in [0, L]
    # (probability L/π), otherwise its maximum is at an end. The bound P(χ²₁ > u) + (L/π) e^{−u/2}
    # counts the ends' share twice: the gate at α is passed at a rate a little below α
    rng = np.random.default_rng(5)
    xi = rng.standard_normal((40_000, 2))
    for length in (0.5, 2.0):
        v = np.linspace(0.0, length, 100)
        U = np.stack([np.cos(v), np.sin(v)])
        G = U.T @ U
        assert abs(arc_length(G, np.ones(v.size, bool)) - length) < 1e-3
        alpha = 0.05
        u = davies_gate(alpha, length)
        rate = float(np.mean(np.max((xi @ U) ** 2, axis=1) > u))
        se = math.sqrt(alpha * (1 - alpha) / xi.shape[0])
        assert rate < alpha + 4 * se and rate > 0.9 * alpha
        # the χ²₁ gate of one value would be passed far more often
        assert float(np.mean(np.max((xi @ U) ** 2, axis=1) > chi2.isf(alpha, 1))) > 1.2 * alpha
        assert effective_tries(alpha, length) > 1.0
    assert davies_gate(0.01, 0.0) == float(chi2.isf(0.01, 1))
