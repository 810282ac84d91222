"""The dwell policy: dwell from a noise window, against the Allan minimum worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.dwell_policy import dwell_from_noise_window, fixed_dwell, longest_noise_window_dwell_s

FS = 100.0


def white_plus_random_walk(n: int, sigma: float, step: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(0, sigma, (n, 3)) + np.cumsum(rng.normal(0, step, (n, 3)), axis=0)


def test_dwell_is_the_allan_minimum_of_white_noise_plus_random_walk() -> None:
    # σ²(τ) = N²/τ + K²τ/3 (IEEE 952) is least at τ* = √3·N/K. With N = σ/√fs and K = step·√fs:
    sigma, fs = 1e-3, FS
    n_white = sigma / math.sqrt(fs)
    tau_star = 5.0
    k = math.sqrt(3) * n_white / tau_star
    choice = dwell_from_noise_window(white_plus_random_walk(60_000, sigma, k / math.sqrt(fs), 1), fs)
    assert choice.source == "noise_window"
    assert choice.dwell_s == pytest.approx(tau_star, rel=0.3)
    assert choice.details["floor_reached"] == "yes"
    assert "noise window" in choice.reason


def test_white_noise_only_says_the_floor_was_not_reached() -> None:
    choice = dwell_from_noise_window(np.random.default_rng(2).normal(0, 1e-3, (12_000, 3)), FS)
    assert choice.details["floor_reached"] == "no"
    assert "still falling" in choice.reason
    assert choice.dwell_s > 20.0  # the longest τ the 120 s window allowed


def test_dwell_is_clipped_and_the_reason_says_so() -> None:
    noise = np.random.default_rng(3).normal(0, 1e-3, (12_000, 3))
    choice = dwell_from_noise_window(noise, FS, max_dwell_s=10.0)
    assert choice.dwell_s == 10.0 and "clipped" in choice.reason


def test_too_short_a_window_and_bad_fixed_dwell_are_refused() -> None:
    with pytest.raises(ValueError, match="noise window too short"):
        dwell_from_noise_window(np.zeros((50, 3)), FS)
    with pytest.raises(ValueError, match="finite and > 0"):
        fixed_dwell(float("nan"))
    assert fixed_dwell(12.0).source == "fixed"


@pytest.mark.parametrize(
    ("window_s", "fs", "tau_max_s"), [(60.0, 250.0, 4096 / 250), (60.0, 100.0, 2048 / 100)]
)
def test_the_longest_dwell_of_a_noise_window_is_its_largest_octave_tau(
    window_s: float, fs: float, tau_max_s: float
) -> None:
    # n = 15000 at 250 Hz: m ≤ 7499, largest power of two 4096; n = 6000 at 100 Hz: 2048
    assert longest_noise_window_dwell_s(window_s, fs) == pytest.approx(tau_max_s)
    white = np.random.default_rng(3).normal(0, 1e-3, (round(window_s * fs), 3))
    assert dwell_from_noise_window(white, fs).dwell_s == pytest.approx(tau_max_s)  # still falling there
    floor = white_plus_random_walk(round(window_s * fs), 1e-3, 1e-4, 4)  # floor near 1 s: a shorter dwell
    assert dwell_from_noise_window(floor, fs).dwell_s < tau_max_s
