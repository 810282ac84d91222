"""The settling test's null distribution without a ring, and a ring it must find.

Null: windows of white Gaussian noise plus a random-walk bias (no ring), the static-12 sizes
(12 windows of 30 s at 100 Hz, 88 frequencies). Each frequency's p value (T_j/(2n) against
F(2n, 3 d_ref)) must be uniform: the share below 0.01 over all frequencies and sets is 0.01
(the frequencies share reference bins, so the count's variance is taken as 1.5 times the
binomial one). With the reference spectrum treated as exact (T_j ~ χ²_2n, the test before
benchmarks/study_settling_null.py) the share is about 1.5 times that (267 against 176
here), which this rejects.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.effects.settling import (
    _segment_spectra,
    detrended_response,
    frequency_p_values,
    settling_test,
)
from bench.diagnosis.thresholds import THRESHOLDS

RATE_HZ = 100.0
N_SETS = 200


def _windows(rng: np.random.Generator, ring_amp: float = 0.0, ring_hz: float = 7.0) -> tuple[np.ndarray, ...]:
    n = round(30.0 * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    out = []
    for _ in range(12):
        x = rng.standard_normal((n, 3)) + np.cumsum(0.003 * rng.standard_normal((n, 3)), axis=0)
        ring = ring_amp * np.exp(-t / 2.0) * np.sin(2 * math.pi * ring_hz * t)
        out.append(x + ring[:, None] * np.array([1.0, 0.5, 0.2]))
    return tuple(out)


def _null_p_values() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(20240)
    p_f, p_chi2 = [], []
    for _ in range(N_SETS):
        _, T, p, n, _ = frequency_p_values(_windows(rng), RATE_HZ)
        p_f.append(p)
        p_chi2.append(chi2_dist.sf(T, 2 * n))
    return np.concatenate(p_f), np.concatenate(p_chi2)


def test_per_frequency_p_values_are_uniform_without_a_ring() -> None:
    p_f, p_chi2 = _null_p_values()
    m = p_f.size
    band = 4.0 * math.sqrt(1.5 * m * 0.01 * 0.99)
    for p, calibrated in ((p_f, True), (p_chi2, False)):
        k = int(np.sum(p < 0.01))
        inside = abs(k - 0.01 * m) < band
        assert inside == calibrated, f"{k} of {m} below 0.01 (expected {0.01 * m:.0f} ± {band:.0f})"
    assert abs(np.mean(p_f) - 0.5) < 0.02


def test_a_decaying_ring_is_found_at_its_frequency() -> None:
    st = settling_test(_windows(np.random.default_rng(5), ring_amp=0.6), RATE_HZ)
    assert st.p_value < 1e-6
    assert st.frequency_hz == 7.0
    assert st.early_power_ratio > 1.2


def test_detrended_response_is_the_mean_periodogram_of_detrended_white_noise() -> None:
    """h_j against 4000 detrended 2 s segments of unit white noise (three channels each): the
    lowest bins lose the share the closed form 1 − 3/(π² j²) (slope, large n) gives."""
    n_seg = round(THRESHOLDS.settling_segment_s * RATE_HZ)
    h = detrended_response(n_seg)
    x = np.random.default_rng(11).standard_normal((4000 * n_seg, 3))
    mean = _segment_spectra(x, n_seg).mean(axis=(0, 2))
    se = 1.0 / np.sqrt(4000 * 3)  # a periodogram ordinate of unit white noise is χ²₂/2
    assert np.all(np.abs(mean[1:-1] - h[1:-1]) < 5 * se)
    for j in (2, 3, 5):
        assert h[j] == pytest.approx(1.0 - 3.0 / (math.pi**2 * j**2), abs=2e-3)
    assert h[2] < 0.93 and h[20] > 0.999


@pytest.mark.parametrize("size", [30.0, 300.0, 3000.0])
def test_one_altered_sample_is_not_a_ring(size: float) -> None:
    """A spike is broadband: its early segment is left out, so over 20 noise sets with one altered
    sample in the first second of a window the test stays at its null (no p below 1e-3, where
    the diagnosis would claim settling: the chance of one in 20 null sets is 2 %)."""
    rng = np.random.default_rng(17)
    for _ in range(20):
        windows = list(_windows(rng))
        w, i, c = rng.integers(12), rng.integers(round(RATE_HZ)), rng.integers(3)
        windows[w] = windows[w].copy()
        windows[w][i, c] += size * rng.choice([-1.0, 1.0])
        assert settling_test(tuple(windows), RATE_HZ).p_value > 1e-3


def test_a_ring_is_found_beside_an_altered_sample() -> None:
    windows = list(_windows(np.random.default_rng(5), ring_amp=0.6))
    windows[3] = windows[3].copy()
    windows[3][50, 0] += 3000.0
    st = settling_test(tuple(windows), RATE_HZ)
    assert st.p_value < 1e-6 and st.frequency_hz == 7.0
