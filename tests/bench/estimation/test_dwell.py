"""The dwell rule: τ* where the window mean's noise stops improving."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.estimation.allan import AllanResult, overlapping_allan
from bench.estimation.dwell import FLAT_FACTOR, recommend_dwell_s
from bench.estimation.noise_terms import BI_FACTOR, basis, fit_noise_model
from tests.support.noise import rate_random_walk, white


def exact_curve(coeffs: list[tuple[float, float, float, float, float]], fs_hz: float = 100.0) -> AllanResult:
    """A noise-free AllanResult of the model with [Q, N, B, K, R] per channel, octave τ to ~2.9 h."""
    taus = 2.0 ** np.arange(21) / fs_hz
    adev = np.stack([np.sqrt(basis(taus) @ np.array([*c, 0.0]) ** 2) for c in coeffs], axis=1)
    edf = np.full(adev.shape, 1e4)
    return AllanResult(
        taus_s=taus,
        adev=adev,
        adev_lo=adev * 0.99,
        adev_hi=adev * 1.01,
        n_pairs=np.full(taus.size, 10**6, dtype=np.int64),
        edf=edf,
        alpha=np.zeros(adev.shape, dtype=np.int64),
        sample_rate_hz=fs_hz,
        n_samples=2**22,
        ci_level=0.6827,
    )


def test_white_plus_random_walk_exact_curve_gives_sqrt3_n_over_k() -> None:
    N, K = 1e-3, 1e-4
    rec = recommend_dwell_s(exact_curve([(0, N, 0, K, 0)]))
    assert rec.dwell_s == pytest.approx(math.sqrt(3) * N / K, rel=1e-5)
    assert rec.floor_reached
    ch = rec.per_channel[0]
    assert ch.dwell_s == pytest.approx(math.sqrt(3) * N / K, rel=1e-5)
    # σ_A at τ*: N²/τ* + K²τ*/3 = 2NK/√3
    assert ch.adev_at_dwell == pytest.approx(math.sqrt(2 * N * K / math.sqrt(3)), rel=1e-6)
    # departure from the white line by √2: K²τ/3 = N²/τ, i.e. τ = √3 N/K as well
    assert ch.white_departure_s == pytest.approx(math.sqrt(3) * N / K, rel=0.01)


def test_flat_floor_gives_first_tau_within_five_percent() -> None:
    """N²/τ + (0.664B)² = 1.05²·(0.664B)²  →  τ = N² / ((1.05² − 1)(0.664B)²)."""
    N, B = 1e-3, 1e-4
    rec = recommend_dwell_s(exact_curve([(0, N, B, 0, 0)]))
    expected = N**2 / ((FLAT_FACTOR**2 - 1) * (BI_FACTOR * B) ** 2)
    assert rec.dwell_s == pytest.approx(expected, rel=0.01)
    assert rec.floor_reached
    assert "flat" in rec.reason


def test_white_noise_only_says_the_record_is_too_short() -> None:
    y = white(np.random.default_rng(2), 100_000, 100.0, 1e-3, 3)
    r = overlapping_allan(y, 100.0)
    rec = recommend_dwell_s(r, channel_names=("ax", "ay", "az"))
    assert not rec.floor_reached
    assert rec.dwell_s == pytest.approx(r.taus_s[-1])
    assert "too short" in rec.reason
    assert all(name in rec.reason for name in ("ax", "ay", "az"))


def test_simulated_white_plus_random_walk_recovers_tau_star() -> None:
    """2 h at 50 Hz, N = 1e-3, K = 1e-4: τ* = √3·N/K = 17.3 s, within what the K uncertainty allows."""
    fs, n, N, K = 50.0, 360_000, 1e-3, 1e-4
    rng = np.random.default_rng(21)
    y = white(rng, n, fs, N, 3) + rate_random_walk(rng, n, fs, K, 3)
    r = overlapping_allan(y, fs)
    fits = fit_noise_model(r, terms=("white", "rate_random_walk"))
    rec = recommend_dwell_s(r, fits)
    tau_star = math.sqrt(3) * N / K
    for fit, ch in zip(fits, rec.per_channel, strict=True):
        # τ* ∝ N/K: relative uncertainty from the two fitted terms
        rel = math.hypot(
            fit.white_n_sigma / fit.white_n, fit.rate_random_walk_k_sigma / fit.rate_random_walk_k
        )
        assert ch.dwell_s == pytest.approx(tau_star, rel=4 * rel)
        assert ch.dwell_s == pytest.approx(tau_star, rel=0.3)
    assert rec.dwell_s == pytest.approx(tau_star, rel=0.3)


def test_overall_dwell_minimises_summed_variance() -> None:
    """Channels with τ* = 10 s and 40 s: the sum N1²/τ + K1²τ/3 + N2²/τ + K2²τ/3 is least at
    √3·√((N1² + N2²)/(K1² + K2²))."""
    c1 = (0.0, 1e-3, 0.0, math.sqrt(3) * 1e-3 / 10, 0.0)
    c2 = (0.0, 2e-3, 0.0, math.sqrt(3) * 2e-3 / 40, 0.0)
    rec = recommend_dwell_s(exact_curve([c1, c2]))
    assert [p.dwell_s for p in rec.per_channel] == pytest.approx([10.0, 40.0], rel=1e-5)
    expected = math.sqrt(3) * math.sqrt((c1[1] ** 2 + c2[1] ** 2) / (c1[3] ** 2 + c2[3] ** 2))
    assert rec.dwell_s == pytest.approx(expected, rel=1e-5)


def test_mismatched_fits_are_rejected() -> None:
    r = exact_curve([(0, 1e-3, 0, 1e-4, 0)] * 2)
    with pytest.raises(ValueError, match="1 noise fits for 2 channels"):
        recommend_dwell_s(r, fit_noise_model(r)[:1])
