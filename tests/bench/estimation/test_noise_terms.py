"""Noise terms from Allan curves: exact model curves, simulated noise, real imu_utils curves.

The noise of known IEEE 952 coefficients comes from ``tests.support.noise``.
"""

from __future__ import annotations

import csv
import math
import re
from collections import defaultdict
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

from bench.estimation.allan import edf_simple, overlapping_allan
from bench.estimation.allan_covariance import allan_correlation, allowance_correlation
from bench.estimation.noise_gls import gls, term_variances
from bench.estimation.noise_terms import (
    BI_FACTOR,
    TERMS,
    basis,
    first_fit_index,
    fit_noise_model,
    fit_noise_model_curve,
    slope_method,
)
from benchmarks.study_sigmas_allan import study
from tests.support.noise import flicker, rate_random_walk, white


def test_bias_instability_factor() -> None:
    assert abs(BI_FACTOR - 0.6642824702) < 1e-9


def test_exact_model_curve_returns_its_coefficients() -> None:
    """A noise-free curve of the model itself is fitted exactly."""
    Q, N, B, K, R = 2e-5, 1e-3, 2e-4, 3e-5, 1e-7
    taus = np.logspace(-2, 4, 40)
    adev = np.sqrt(basis(taus) @ np.array([Q, N, B, K, R, 0.0]) ** 2)
    fit = fit_noise_model_curve(taus, adev, np.full(taus.size, 1e4))
    got = [fit.quantization_q, fit.white_n, fit.bias_instability_b, fit.rate_random_walk_k, fit.rate_ramp_r]
    np.testing.assert_allclose(got, [Q, N, B, K, R], rtol=1e-6)
    assert fit.chi2_dof < 1e-10
    np.testing.assert_allclose(fit.model_adev(taus), adev, rtol=1e-9)


def test_flicker_generator_has_its_defining_spectrum() -> None:
    """Averaged periodogram of :func:`flicker` against S(f) = h/f, h = B²/π, band by band.

    One-sided periodogram P = 2|X|²/(n·fs); each band's mean of P·f/h pools b bins × 8
    records of independent exponential ordinates: relative standard error 1/√(8b), bound 4×.
    """
    fs, n, B, reps = 100.0, 1 << 16, 2e-4, 8
    f = np.fft.rfftfreq(n, 1.0 / fs)
    ratio = np.zeros(f.size)
    for seed in range(reps):
        y = flicker(np.random.default_rng(50 + seed), n, fs, B, 1)[:, 0]
        ratio += np.abs(np.fft.rfft(y)) ** 2 * 2.0 / (n * fs) * f / (B**2 / math.pi) / reps
    for lo, hi in [(0.01, 0.1), (0.1, 1.0), (1.0, 10.0), (10.0, 49.0)]:
        band = (f >= lo) & (f < hi)
        tol = 4.0 / math.sqrt(reps * band.sum())
        assert ratio[band].mean() == pytest.approx(1.0, abs=tol), (lo, hi)


def test_sigmas_are_honest_over_many_seeds() -> None:
    """z = (estimate − truth)/sigma over 20 seeds × 3 channels: spread within 0.8–1.25, no resolvable offset.

    One hour at 100 Hz of white + flicker + rate random walk; the three terms present are
    fitted. Offset bound 3·sd/√60. A square-root coefficient estimated from a scale-type
    quantity (σ² ∝ K²) with a sigma that scales with the estimate reads z ≈ −0.25 on average at
    ~20 % relative sigma (E[1/√X] > 1 for X ~ χ²_ν/ν, ν ≈ 15), inside that bound for K.
    Measured with this seed set: sd(z) N 0.89, B 0.82, K 0.97; mean(z) −0.10, +0.19, −0.32.
    """
    fs, n = 100.0, 360_000
    N, B, K = 1e-3, 2e-4, 5e-5
    terms = ("white", "bias_instability", "rate_random_walk")
    z, rel = [], []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        y = white(rng, n, fs, N, 3) + flicker(rng, n, fs, B, 3) + rate_random_walk(rng, n, fs, K, 3)
        for fit in fit_noise_model(overlapping_allan(y, fs), terms):
            z.append(
                [
                    (fit.white_n - N) / fit.white_n_sigma,
                    (fit.bias_instability_b - B) / fit.bias_instability_b_sigma,
                    (fit.rate_random_walk_k - K) / fit.rate_random_walk_k_sigma,
                ]
            )
            rel.append(
                [fit.white_n_sigma / N, fit.bias_instability_b_sigma / B, fit.rate_random_walk_k_sigma / K]
            )
    zs = np.array(z)
    # and the sigmas are informative: median relative sigma N < 1 %, B < 35 %, K < 30 %
    assert np.all(np.median(rel, axis=0) < [0.01, 0.35, 0.30]), np.median(rel, axis=0)
    sd = zs.std(axis=0, ddof=1)
    assert np.all((sd > 0.8) & (sd < 1.25)), sd
    assert np.all(np.abs(zs.mean(axis=0)) < 3.0 * sd / math.sqrt(len(zs))), zs.mean(axis=0)


def test_allan_correlation_of_white_noise_matches_simulation() -> None:
    """Octave-neighbour correlation of σ̂² for white noise: spectral formula vs 400 simulated curves.

    Standard error of a correlation from 400 pairs ≈ (1 − ρ²)/√400 ≈ 0.04: 4σ = 0.16.
    """
    fs, n = 1.0, 8192
    sims = np.array(
        [
            overlapping_allan(white(np.random.default_rng(300 + s), n, fs, 1.0, 1), fs).avar[:, 0]
            for s in range(400)
        ]
    )
    taus = np.arange(sims.shape[1], dtype=float)
    taus = 2.0**taus
    rho = allan_correlation(taus, [0.0, 1.0, 0.0, 0.0, 0.0], 1.0)
    emp = np.corrcoef(sims.T)
    for k in range(2, 7):  # τ = 4 … 64 samples: long against τ0, short against the record
        assert emp[k, k + 1] == pytest.approx(rho[k, k + 1], abs=0.16), k
        assert emp[k, k + 2] == pytest.approx(rho[k, k + 2], abs=0.16), k


def test_allowance_correlation_is_exponential_in_octaves() -> None:
    taus = np.array([1.0, 2.0, 8.0])
    np.testing.assert_array_equal(allowance_correlation(taus, 0.0), np.eye(3))
    rho = allowance_correlation(taus, 2.0)
    assert rho[0, 1] == pytest.approx(math.exp(-0.5)) and rho[0, 2] == pytest.approx(math.exp(-1.5))
    np.testing.assert_allclose(rho, rho.T)


def test_sandwich_with_the_fits_own_covariance_is_its_normal_matrix() -> None:
    """H⁻¹AsᵀL⁻¹·C·L⁻ᵀAsH⁻¹ with C = L·Lᵀ (the fit's covariance) reduces to H⁻¹ = (AsᵀAs)⁻¹."""
    taus = np.asarray(0.01 * 2.0 ** np.arange(14), dtype=np.float64)
    rng = np.random.default_rng(3)
    s2: npt.NDArray[np.float64] = (basis(taus)[:, :5] @ np.array([0.0, 1e-3, 2e-4, 2e-5, 0.0]) ** 2) * (
        1 + 0.01 * rng.normal(size=14)
    )
    nu = np.asarray(3e5 * 0.01 / taus, dtype=np.float64)
    fit = gls(taus, s2, nu, basis(taus)[:, :5], [0, 1, 2, 3, 4], 0.01, 0.02, 3)
    np.testing.assert_allclose(term_variances(fit, 1.0, fit.L @ fit.L.T), term_variances(fit, 1.0), rtol=1e-6)


def test_correlated_misfit_widens_the_white_sigma() -> None:
    """White noise plus a Gauss–Markov bias of 0.3 s (a hump no power law makes) on a dense τ
    grid at edf 7·10³-7·10⁵ (about 2 h at 100 Hz): χ² fails and the misfit is smooth in τ. N is
    ambiguous there (1e-3 at short τ, √(N² + 2q·T_c) = 1.26e-3 beyond the hump); the fit reads
    1.06e-3. With the allowance independent between τ its sigma leaves the short-τ density
    more than 4σ away; at the allowance's likelihood length it is within 2σ. The values are
    those of the independent allowance either way.
    """
    taus = np.geomspace(0.01, 1000.0, 60)
    tc, q = 0.3, (1e-3) ** 2  # Allan variance of a Gauss–Markov process (IEEE 952 C.6)
    x = taus / tc
    gm = q / x**2 * (2 * x - 3 + 4 * np.exp(-x) - np.exp(-2 * x))
    adev = np.sqrt(basis(taus)[:, :5] @ np.array([0.0, 1e-3, 0.0, 2e-5, 0.0]) ** 2 + gm)
    edf = 7e5 * 0.01 / taus
    power_laws = TERMS[:5]  # without the Gauss–Markov term, which describes this curve exactly
    free = fit_noise_model_curve(taus, adev, edf, power_laws, tau0_s=0.01)
    independent = fit_noise_model_curve(taus, adev, edf, power_laws, tau0_s=0.01, floor_octaves=0.0)
    assert free.model_floor_rel > 0 and free.model_floor_corr_octaves > 0
    assert free.white_n == independent.white_n
    assert abs(independent.white_n - 1e-3) > 4.0 * independent.white_n_sigma
    assert abs(free.white_n - 1e-3) < 2.0 * free.white_n_sigma


def test_sigmas_cover_the_spread_between_recordings() -> None:
    """Sampled ``benchmarks.study_sigmas_allan``: 6 recordings × 3 channels of 1200 s of white
    noise, a Gauss–Markov bias and rate random walk. RMS over the 153 pairs of |Δ| / combined
    sigma within 0.4-1.6 for N, B, K (18 values: about ±25 % on each; the 50-recording study
    at 600, 3000 and 12000 s is in docs/noise-model.md).
    """
    res = study(6, 1200.0)
    for name in ("N_fit", "B_fit", "K_fit"):
        assert 0.4 < res[f"{name}_pair_z"] < 1.6, (name, res)


def test_sigmas_cover_the_spread_on_short_power_law_records() -> None:
    """Sampled ``benchmarks.study_sigmas_allan`` on the ``powerlaw`` sensor (white, flicker, rate
    random walk; no quantisation, no ramp): 8 recordings × 3 channels of 600 s. Pair z and z
    against the truth within 0.6-1.5 for N, B and K (24 values: about ±20 % on each; the
    50-recording figures are in docs/noise-model.md). With quantisation and ramp always in the
    normal matrix, their trade read N 0.80, B 0.69, K 0.41 (pair z, 24 recordings).
    """
    res = study(8, 600.0, sensor="powerlaw")
    for name in ("N_fit", "B_fit", "K_fit"):
        assert 0.6 < res[f"{name}_pair_z"] < 1.5, (name, res)
        assert 0.6 < res[f"{name}_truth_z"] < 1.5, (name, res)


def test_quantisation_and_ramp_enter_only_where_the_curve_needs_them() -> None:
    """An exact curve with Q and R keeps them (see the exact-curve test); white noise plus rate
    random walk at edf of 2 h leaves them out: value 0 and a positive one-sigma upper limit,
    while the same fit with selection off still counts them in N's sigma (wider)."""
    taus = np.asarray(0.01 * 2.0 ** np.arange(16), dtype=np.float64)
    rng = np.random.default_rng(5)
    truth = basis(taus)[:, :5] @ np.array([0.0, 1e-3, 0.0, 2e-5, 0.0]) ** 2
    nu = np.asarray(7.2e5 * 0.01 / taus + 2.0, dtype=np.float64)
    adev = np.sqrt(truth * rng.chisquare(nu) / nu)
    sel = fit_noise_model_curve(taus, adev, nu, tau0_s=0.01)
    full = fit_noise_model_curve(taus, adev, nu, tau0_s=0.01, select=False)
    assert sel.quantization_q == 0.0 and sel.rate_ramp_r == 0.0
    assert sel.quantization_q_sigma > 0 and sel.rate_ramp_r_sigma > 0
    assert sel.white_n_sigma < full.white_n_sigma


def test_white_noise_alone_leaves_other_terms_near_zero() -> None:
    fs, n, N = 200.0, 200_000, 5e-4
    y = white(np.random.default_rng(9), n, fs, N, 2)
    for fit in fit_noise_model(overlapping_allan(y, fs)):
        assert fit.white_n == pytest.approx(N, abs=3.5 * fit.white_n_sigma)
        # every other term is 0 or below its 3.5-sigma limit, and would move σ_A at 1 s by < 3 %
        for name in ("bias_instability_b", "rate_random_walk_k", "rate_ramp_r"):
            assert getattr(fit, name) <= 3.5 * max(getattr(fit, f"{name}_sigma"), 1e-30)
        assert float(fit.model_adev(1.0)) == pytest.approx(N, rel=0.03)


def test_slope_method_reads_the_lines() -> None:
    """White + rate random walk: N on the −1/2 line at 1 s, K on the +1/2 line at 3 s (IEEE 952 C)."""
    fs, n, N, K = 50.0, 500_000, 2e-3, 2e-4
    rng = np.random.default_rng(4)
    y = white(rng, n, fs, N, 2) + rate_random_walk(rng, n, fs, K, 2)
    for s in slope_method(overlapping_allan(y, fs)):
        assert s.method == "ieee952-slope"
        assert s.white_n == pytest.approx(N, rel=0.01)
        assert s.rate_random_walk_k == pytest.approx(K, rel=0.3)
        # no flat region: B is the minimum / 0.664, an upper bound; the minimum of N²/τ + K²τ/3
        assert s.bias_instability_b * BI_FACTOR == pytest.approx(math.sqrt(2 * N * K / math.sqrt(3)), rel=0.2)


def test_rising_start_is_left_out() -> None:
    assert first_fit_index([1.0, 2.0, 3.0, 2.5, 2.0]) == 2
    assert first_fit_index([3.0, 2.0, 1.0, 2.0]) == 0
    assert first_fit_index([1.0, 2.0, 3.0]) == 0


def test_bad_curve_is_named() -> None:
    with pytest.raises(ValueError, match="unknown noise terms"):
        fit_noise_model_curve([1.0, 2.0, 4.0], [1.0, 0.7, 0.5], [10, 10, 10], terms=("pink",))
    with pytest.raises(ValueError, match="cannot determine"):
        fit_noise_model_curve([1.0, 2.0], [1.0, 0.7], [10, 10])
    with pytest.raises(ValueError, match="finite"):
        fit_noise_model_curve([1.0, 2.0, 4.0, 8.0], [1.0, np.nan, 0.5, 0.3], [10] * 4, terms=("white",))


# --- real curves: imu_utils (gaowenliang/imu_utils data/, six IMUs, ~2 h static) ----------------

IMU_UTILS_RATE_HZ = {"xsens": 100.0, "16448": 200.0, "gx4": 500.0, "A3": 400.0, "N3": 400.0, "BMI160": 196.0}


def _imu_utils_acc(real_dir: Path) -> dict[str, list[dict[str, str]]]:
    rows: dict[str, list[dict[str, str]]] = defaultdict(list)
    with (real_dir / "imu_utils-allan/imu_utils_allan_curves.csv").open() as fh:
        for row in csv.DictReader(fh):
            if row["quantity"] == "acc":
                rows[row["sensor"]].append(row)
    return rows


def _yaml_acc(real_dir: Path, sensor: str, axis: str) -> tuple[float, float]:
    text = (real_dir / f"imu_utils-allan/original/{sensor}_imu_param.yaml").read_text()
    block = text[text.index("Acc:") :]
    block = block[block.index(f"{axis}-axis:") :]
    acc_n = re.search(r"acc_n:\s*(\S+)", block)
    acc_w = re.search(r"acc_w:\s*(\S+)", block)
    assert acc_n and acc_w
    return float(acc_n.group(1)), float(acc_w.group(1))


@pytest.mark.slow  # 24 s: Allan fits of the 18 published curves
def test_imu_utils_curves_give_their_published_noise_levels(real_dir: Path) -> None:
    """Our fit of imu_utils' own Allan curves lands near the acc_n, acc_w its YAML files publish.

    imu_utils reports acc_n = its fitted model's σ_A at τ = 1 s (all terms, not N alone) and
    acc_w = the minimum of its fitted model over the curve's τ (not divided by 0.664)
    (src/acc_lib/fitallan_acc.h: getWhiteNoise, getBiasInstability). We compare like with like.

    Tolerances and why. Our model at 1 s within 12 % of the measured curve at 1 s (edf ~ 10⁴
    there, so this is model misfit, not noise: up to ~10 % on the DJI A3/N3, whose short-τ
    filter hump no power-law model describes). Within 15 % of acc_n: imu_utils fits log σ²
    unweighted, and its own model sits up to 15 % off its data at 1 s (ADIS16448 y: data
    0.87 × acc_n). Floor within 35 % of acc_w: the minimum lies in the last octaves of a 2 h
    record, where each point has edf < 20 (±15-25 % per point, and neighbours correlated)
    and the bias-instability / random-walk split is weakly determined, so two fitting
    methods legitimately differ by that much (largest seen: DJI N3 z, +34 %). BMI160: its
    YAML is ~15× off its own curves (see the data README), so its σ_A(1 s) is compared with
    imu_utils' fitted curve file instead of the YAML.
    """
    curves = _imu_utils_acc(real_dir)
    assert set(curves) == set(IMU_UTILS_RATE_HZ)
    n_checked = 0
    for sensor, rows in curves.items():
        taus = np.array([float(r["tau_s"]) for r in rows])
        tau0 = 1.0 / IMU_UTILS_RATE_HZ[sensor]
        n_samples = round(2 * 3600 / tau0)
        m = np.maximum(np.rint(taus / tau0).astype(int), 1)
        edf = np.array([edf_simple(n_samples + 1, int(k), 0) for k in m])
        for axis in "xyz":
            adev = np.array([float(r[f"adev_{axis}"]) for r in rows])
            fit = fit_noise_model_curve(taus, adev, edf)
            acc_n, acc_w = _yaml_acc(real_dir, sensor, axis)
            if sensor == "BMI160":
                their_fit = np.array([float(r[f"fit_{axis}"]) for r in rows])
                acc_n = float(np.exp(np.interp(0.0, np.log(taus), np.log(their_fit))))
            ours_1s = float(fit.model_adev(1.0))
            measured_1s = float(np.exp(np.interp(0.0, np.log(taus), np.log(adev))))
            ours_floor = float(np.min(fit.model_adev(taus)))
            assert ours_1s == pytest.approx(measured_1s, rel=0.12), (sensor, axis)
            assert ours_1s == pytest.approx(acc_n, rel=0.15), (sensor, axis)
            assert ours_floor == pytest.approx(acc_w, rel=0.35), (sensor, axis)
            # the white density alone is below the all-term value at 1 s, never above it
            assert fit.white_n <= ours_1s * (1 + 1e-9)
            n_checked += 1
    assert n_checked == 18


@pytest.mark.slow  # about 2 min: 36 fits of 81-point curves with the allowance's length searched
def test_white_sigma_covers_imu_utils_reading_of_the_same_curves(real_dir: Path) -> None:
    """N of each measured imu_utils curve against N of the same fit applied to imu_utils' own
    model curve (a second reading of one recording): z = ΔN / σ_N over the 18 curves.

    Most curves fail χ² (a short-τ filter hump, no clean −1/2 region on the DJI A3/N3), so the
    two readings differ by what the model leaves out, not by noise. With the allowance
    independent between τ, RMS z was 4.9 and |z| reached 9.9 (N sigma 1-2 %); the bound
    is RMS z < 2 and every |z| < 3.5 (measured: docs/noise-model.md).
    """
    curves = _imu_utils_acc(real_dir)
    z = []
    for sensor, rows in curves.items():
        taus = np.array([float(r["tau_s"]) for r in rows])
        tau0 = 1.0 / IMU_UTILS_RATE_HZ[sensor]
        m = np.maximum(np.rint(taus / tau0).astype(int), 1)
        edf = np.array([edf_simple(round(2 * 3600 / tau0) + 1, int(k), 0) for k in m])
        for axis in "xyz":
            ours = fit_noise_model_curve(
                taus, np.array([float(r[f"adev_{axis}"]) for r in rows]), edf, tau0_s=tau0
            )
            theirs = fit_noise_model_curve(
                taus, np.array([float(r[f"fit_{axis}"]) for r in rows]), edf, tau0_s=tau0
            )
            z.append((ours.white_n - theirs.white_n) / ours.white_n_sigma)
    za = np.abs(np.array(z))
    assert za.size == 18
    assert math.sqrt(float(np.mean(za**2))) < 2.0 and za.max() < 3.5, np.round(z, 2)
