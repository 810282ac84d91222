"""Overlapping Allan deviation: published NBS14 values, allantools, and known noise levels."""

from __future__ import annotations

import json
import math
from pathlib import Path

import allantools
import numpy as np
import pytest
from allantools import ci as at_ci

from bench.estimation.allan import averaging_factors, edf_simple, overlapping_allan

NBS14 = json.loads((Path(__file__).resolve().parents[2] / "data" / "nbs14_oadev.json").read_text())


def nbs14_1000() -> np.ndarray:
    """The NBS14 1000-point data set from its published generator (SP1065 p. 107)."""
    ref = NBS14["thousand_point"]
    n = [1234567890]
    for _ in range(999):
        n.append((16807 * n[-1]) % 2147483647)
    assert n[1:4] == ref["first_values_check"]
    return np.array(n, dtype=float) / 2147483647


def test_nbs14_ten_point_frequency_data() -> None:
    ref = NBS14["ten_point"]
    r = overlapping_allan(ref["frequency"], ref["sample_rate_hz"], ref["taus_s"])
    np.testing.assert_allclose(r.adev[:, 0], ref["oadev"], rtol=2e-6)
    np.testing.assert_array_equal(r.taus_s, ref["taus_s"])


def test_nbs14_thousand_point() -> None:
    ref = NBS14["thousand_point"]
    r = overlapping_allan(nbs14_1000(), ref["sample_rate_hz"], ref["taus_s"])
    np.testing.assert_allclose(r.adev[:, 0], ref["oadev"], rtol=2e-6)


@pytest.mark.parametrize("taus", ["octave", "decade", [0.01, 0.03, 0.25, 1.0, 7.77]])
def test_agrees_with_allantools_oadev(taus: object) -> None:
    rng = np.random.default_rng(7)
    n, fs = 20_000, 100.0
    y = 9.81 + rng.normal(scale=0.01, size=(n, 3)) + np.cumsum(rng.normal(scale=1e-4, size=(n, 3)), axis=0)
    r = overlapping_allan(y, fs, taus)  # type: ignore[arg-type]
    for c in range(3):
        t_ref, dev_ref, _, n_ref = allantools.oadev(y[:, c], rate=fs, data_type="freq", taus=taus)
        np.testing.assert_array_equal(r.taus_s, t_ref)
        np.testing.assert_array_equal(r.n_pairs, n_ref)
        np.testing.assert_allclose(r.adev[:, c], dev_ref, rtol=1e-10, atol=0)


def test_one_dimensional_input_gives_one_channel() -> None:
    y = np.random.default_rng(0).normal(size=1000)
    r1 = overlapping_allan(y, 10.0)
    r2 = overlapping_allan(y[:, None], 10.0)
    assert r1.adev.shape == (r1.taus_s.size, 1)
    np.testing.assert_array_equal(r1.adev, r2.adev)


def test_white_noise_level_and_slope() -> None:
    """White noise of σ per sample: σ_A(τ) = σ/√(τ·f_s), SP1065 Table 2 (white FM), slope −1/2."""
    sigma, fs, n = 0.02, 200.0, 400_000
    y = np.random.default_rng(11).normal(scale=sigma, size=(n, 2))
    r = overlapping_allan(y, fs)
    expected = sigma / np.sqrt(r.taus_s * fs)
    ok = r.edf[:, 0] > 30  # enough degrees of freedom for a 4-sigma check
    for c in range(2):
        z = (r.adev[ok, c] - expected[ok]) / (expected[ok] / np.sqrt(2 * r.edf[ok, c]))
        assert np.all(np.abs(z) < 4.5), z
        slope = np.polyfit(np.log(r.taus_s[ok]), np.log(r.adev[ok, c]), 1)[0]
        assert slope == pytest.approx(-0.5, abs=0.02)
    assert np.all(r.alpha[r.taus_s < 1.0] == 0)


def test_random_walk_level_and_slope() -> None:
    """Rate random walk y_k = Σ K/√f_s·w: σ_A(τ) = K·√(τ/3) for τ ≫ 1/f_s, slope +1/2 (IEEE 952 C.2)."""
    K, fs, n = 3e-4, 100.0, 200_000
    rng = np.random.default_rng(5)
    y = np.cumsum(K / np.sqrt(fs) * rng.normal(size=(n, 4)), axis=0)
    r = overlapping_allan(y, fs)
    sel = (r.taus_s >= 0.5) & (r.edf[:, 0] > 5)
    for c in range(4):
        slope = np.polyfit(np.log(r.taus_s[sel]), np.log(r.adev[sel, c]), 1)[0]
        assert slope == pytest.approx(0.5, abs=0.08)
    # the level, pooled over the four channels at τ = 1.28 s (edf ≈ 4 × 3e3)
    i = int(np.argmin(np.abs(r.taus_s - 1.28)))
    pooled = math.sqrt(np.mean(r.adev[i] ** 2))
    assert pooled == pytest.approx(K * math.sqrt(r.taus_s[i] / 3), rel=0.05)
    assert np.all(r.alpha[1:8] == -2)


@pytest.mark.parametrize("alpha", [2, 1, 0, -1, -2])
def test_edf_matches_allantools_simple_formula(alpha: int) -> None:
    for n_phase, m in [(1001, 1), (1001, 10), (36001, 128), (500, 100)]:
        expected = at_ci.edf_simple(n_phase, m, alpha)
        assert edf_simple(n_phase, m, alpha) == pytest.approx(max(expected, 1.0), rel=1e-12)


def test_interval_matches_allantools_chi2_interval() -> None:
    y = np.random.default_rng(3).normal(size=(5000, 1))
    r = overlapping_allan(y, 1.0)
    for k in range(r.taus_s.size):
        lo, hi = at_ci.confidence_interval(r.adev[k, 0], r.edf[k, 0])
        assert r.adev_lo[k, 0] == pytest.approx(lo, rel=1e-9)
        assert r.adev_hi[k, 0] == pytest.approx(hi, rel=1e-9)
        assert r.adev_lo[k, 0] < r.adev[k, 0] < r.adev_hi[k, 0]


def test_interval_covers_truth_at_its_stated_rate() -> None:
    """300 independent white-noise channels: the 68 % interval holds the true σ_A in 68 ± 8 % of them."""
    sigma, n, n_ch = 1.0, 4000, 300
    y = np.random.default_rng(123).normal(scale=sigma, size=(n, n_ch))
    r = overlapping_allan(y, 1.0, [1, 4, 16, 64])
    truth = sigma / np.sqrt(r.taus_s)[:, None]
    coverage = np.mean((r.adev_lo <= truth) & (truth <= r.adev_hi), axis=1)
    assert np.all(np.abs(coverage - r.ci_level) < 0.08), coverage


def test_octave_taus_stop_where_two_differences_remain() -> None:
    m = averaging_factors(1000, 1.0, "octave")
    assert m.tolist() == [1, 2, 4, 8, 16, 32, 64, 128, 256]
    assert averaging_factors(11, 1.0, "all").tolist() == [1, 2, 3, 4, 5]


@pytest.mark.parametrize(
    ("y", "fs", "taus", "match"),
    [
        (np.array([1.0, 2.0, np.nan, 4.0, 5.0]), 1.0, None, "non-finite value.*sample 2, channel 0"),
        (np.ones((10, 2)), 0.0, None, "sample_rate_hz"),
        (np.ones((10, 2)), float("nan"), None, "sample_rate_hz"),
        (np.ones(2), 1.0, None, "at least 3 samples"),
        (np.ones((4, 2, 2)), 1.0, None, "shape"),
        (np.ones(100), 1.0, [0.2], "tau 0.2 s is outside"),
        (np.ones(100), 1.0, [60.0], "tau 60 s is outside"),
        (np.ones(100), 1.0, "weekly", "taus_s must be"),
    ],
)
def test_bad_input_is_named(y: np.ndarray, fs: float, taus: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        overlapping_allan(y, fs, taus)  # type: ignore[arg-type]


def test_edf_never_rises_with_tau() -> None:
    """White + flicker + random walk, identified α 0 → −1 → 0: Table 5 alone rises, the edf does not."""
    from tests.support.noise import flicker, rate_random_walk, white

    rng = np.random.default_rng(3)
    n = 100_000
    y = (
        white(rng, n, 100.0, 1e-3, 2)
        + flicker(rng, n, 100.0, 3e-4, 2)
        + rate_random_walk(rng, n, 100.0, 3e-5, 2)
    )
    r = overlapping_allan(y, 100.0)
    ms = np.rint(r.taus_s * 100.0).astype(int)
    own = np.array([edf_simple(n + 1, int(m), r.alpha[k]) for k, m in enumerate(ms)])
    assert np.any(np.diff(own, axis=0) > 0)  # the case the rule is for
    assert np.all(np.diff(r.edf, axis=0) <= 0.0)
    assert np.all(r.edf <= own + 1e-9)  # each value is its own α's, or a shorter τ's smaller one
    np.testing.assert_allclose(r.edf, np.minimum.accumulate(own, axis=0))
