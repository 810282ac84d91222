"""Periodic lines: found with their frequency and amplitude, absent from noise, removed cleanly."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from bench.estimation.allan import overlapping_allan
from bench.estimation.spectral_lines import find_lines, local_median, remove_lines, welch_segment_length
from tests.support.noise import flicker, rate_random_walk, white

FS = 100.0
N_SAMPLES = 200_000


def _noise(seed: int, c: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    n = N_SAMPLES
    return white(rng, n, FS, 1e-3, c) + flicker(rng, n, FS, 2e-4, c) + rate_random_walk(rng, n, FS, 5e-5, c)


def test_lines_found_with_frequency_amplitude_and_channel() -> None:
    """Amplitude from ∫(P − M) df = A²/2; bounds 10 % (the line's power is ~10⁴ noise bins' worth)."""
    y = _noise(1)
    t = np.arange(N_SAMPLES) / FS
    y[:, 0] += 0.01 * np.sin(2 * np.pi * 0.5 * t + 1.0)
    y[:, 2] += 0.004 * np.cos(2 * np.pi * 23.4 * t)
    lines = find_lines(y, FS)
    assert [(ln.channel, round(ln.frequency_hz, 2)) for ln in lines] == [(0, 0.5), (2, 23.4)]
    assert lines[0].amplitude == pytest.approx(0.01, rel=0.1)
    assert lines[1].amplitude == pytest.approx(0.004, rel=0.1)
    assert all(ln.ratio_to_median > 100 for ln in lines)


def test_noise_alone_has_no_line() -> None:
    """False-alarm rate 10⁻³ per analysis by design: ten seeds of power-law noise give none (P(any) ≈ 1 %)."""
    for seed in range(10):
        assert find_lines(_noise(100 + seed, 2), FS) == (), seed


def test_a_broad_resonance_is_not_a_line() -> None:
    """White noise through a resonator of Q = 5 at 10 Hz: a peak ~2 Hz wide, far wider than 8 bins."""
    rng = np.random.default_rng(4)
    b, a = signal.iirpeak(10.0, 5.0, fs=FS)
    y = signal.lfilter(b, a, rng.normal(size=N_SAMPLES)) * 30.0 + rng.normal(size=N_SAMPLES)
    assert find_lines(y, FS) == ()


def test_local_median_follows_a_power_law_and_ignores_a_spike() -> None:
    k = np.arange(1, 4001, dtype=float)
    p = 1.0 / k**2
    spiked = p.copy()
    spiked[1000] *= 1e4
    med = local_median(spiked)
    # a monotone spectrum's median over a symmetric window is its centre value; the window is
    # cut below bin 8 and beyond bin 8k/9, and log-interpolation between centres costs < 1 %
    np.testing.assert_allclose(med[16:3500], p[16:3500], rtol=0.01)


def test_removal_takes_the_line_out_and_leaves_the_noise() -> None:
    """After removal the line's bin is back at the noise level and σ_A of the noise is unchanged to 1 %."""
    y0 = _noise(7, 1)[:, 0]
    t = np.arange(N_SAMPLES) / FS
    y = y0 + 0.02 * np.sin(2 * np.pi * (0.5 + 3e-4) * t)  # off the Welch bin centre
    lines = find_lines(y, FS)
    clean, refined = remove_lines(y, FS, lines)
    assert refined[0].frequency_hz == pytest.approx(0.5003, abs=2e-5)
    assert find_lines(clean, FS) == ()
    a0 = overlapping_allan(y0, FS).adev[:, 0]
    a1 = overlapping_allan(clean, FS).adev[:, 0]
    np.testing.assert_allclose(a1[:12], a0[:12], rtol=0.01)


def test_segment_length_and_bad_input() -> None:
    assert welch_segment_length(200_000) == 16384
    assert welch_segment_length(1000) == 256
    with pytest.raises(ValueError, match="n ≥ 64"):
        find_lines(np.zeros(10), FS)
    with pytest.raises(ValueError, match="sample_rate_hz"):
        find_lines(np.zeros(100), math.nan)


SHORT = 5200  # 52 s at 100 Hz: the first pass's floor, 8 fs / 512 = 1.56 Hz, is above 0.5 Hz


def _short_noise(seed: int, c: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return white(rng, SHORT, FS, 1e-3, c) + flicker(rng, SHORT, FS, 2e-4, c)


def test_a_slow_line_in_a_short_record_is_found_by_the_low_frequency_pass() -> None:
    """A 0.5 Hz line of 3× the white noise's per-sample sigma (26 periods in 52 s): found on
    its channel, frequency within one low-pass bin (fs / 4096 = 0.024 Hz), amplitude within 10 %
    (its power is ~10³ noise bins' worth); the Allan white level after removal is the noise's."""
    y = _short_noise(21)
    t = np.arange(SHORT) / FS
    amp = 0.03  # white sigma per sample 1e-3 · √100 = 0.01
    y[:, 1] += amp * np.sin(2 * np.pi * 0.5 * t + 0.3)
    lines = find_lines(y, FS)
    assert [ln.channel for ln in lines] == [1]
    assert lines[0].frequency_hz == pytest.approx(0.5, abs=FS / 4096)
    assert lines[0].amplitude == pytest.approx(amp, rel=0.1)
    clean, _ = remove_lines(y, FS, lines)
    taus = np.array([0.01, 0.02, 0.04])  # white-dominated τ: σ_A = N / √τ, N = 1e-3
    a = overlapping_allan(clean[:, 1], FS, taus).adev[:, 0]
    np.testing.assert_allclose(a * np.sqrt(taus), 1e-3, rtol=0.1)


def test_short_records_of_noise_alone_have_no_line() -> None:
    """Both passes on 52 s records: 20 seeds of white + flicker noise give none (design
    false-alarm 10⁻³ per analysis, so P(any over 20) ≈ 2 %)."""
    for seed in range(20):
        assert find_lines(_short_noise(300 + seed), FS) == (), seed
