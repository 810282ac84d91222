"""Bench physics in what the model leaves: periodic lines, angle harmonics, clock drift, the last
move's direction (bench/diagnosis/periodic_lines.py, motion_families.py, hysteresis.py)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.diagnosis.hysteresis import last_move_sign
from bench.diagnosis.motion_families import clock_drift, drift_passes, find_families, search_harmonics
from bench.diagnosis.periodic_lines import find_periodic_lines

FS = 100.0


def _windows(
    rng: np.random.Generator, amp: float, f0: float, phase: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """12 windows of 10 s, 5 s apart, white noise 1e-3 plus a line on channel 0 (phase kept across gaps)."""
    out = []
    for w in range(12):
        t = 15.0 * w + np.arange(1000) / FS
        y = 1e-3 * rng.standard_normal((t.size, 3)) + 0.5 * w
        y[:, 0] += amp * np.sin(2 * np.pi * f0 * t + phase)
        out.append((t, y))
    return out


def test_line_in_windows_is_measured_on_its_own_clock() -> None:
    lines = find_periodic_lines(_windows(np.random.default_rng(1), 6e-4, 2.5, 0.7), FS)
    assert len(lines) == 1 and lines[0].channels == (0,)
    ln = lines[0]
    assert abs(ln.frequency_hz - 2.5) < 3 * ln.frequency_sigma_hz
    assert abs(ln.amplitude[0] - 6e-4) < 3 * ln.amplitude_sigma[0]
    # by hand: white sigma 1e-3 over N = 12000 samples: sigma_A = 1e-3 * sqrt(2 / N)
    assert ln.amplitude_sigma[0] == pytest.approx(1e-3 * np.sqrt(2 / 12000), rel=0.15)
    assert abs(np.angle(np.exp(1j * (ln.phase_rad[0] - 0.7)))) < 0.1


def test_a_fast_line_in_short_gapped_windows_stays_a_line() -> None:
    """40 windows of 8 s, 4 s apart (a hand-placed tumble), white noise 3.6 per sample and a
    23.4 Hz line of 5 on channel 1 whose phase runs on across the gaps. Laid end to end the
    samples jump in the line's phase at every junction; a Welch segment spanning several
    windows widened the peak beyond MAX_LINE_BINS. By hand: σ_A = 3.6 · √(2 / 32000)."""
    rng = np.random.default_rng(8)
    pieces = []
    for w in range(40):
        t = 12.0 * w + np.arange(800) / FS
        y = 3.6 * rng.standard_normal((t.size, 3))
        y[:, 1] += 5.0 * np.sin(2 * np.pi * 23.4 * t + 0.4)
        pieces.append((t, y))
    (ln,) = find_periodic_lines(pieces, FS)
    assert ln.channels == (1,)
    assert ln.amplitude_sigma[1] == pytest.approx(3.6 * np.sqrt(2 / 32000), rel=0.15)
    assert abs(ln.amplitude[1] - 5.0) < 4 * ln.amplitude_sigma[1]
    assert abs(ln.frequency_hz - 23.4) < 4 * ln.frequency_sigma_hz


@pytest.mark.slow
def test_line_sigmas_are_the_scatter_and_noise_alone_gives_none() -> None:
    """30 seeds: z of the amplitude has RMS within [0.65, 1.35] (30 honest z: 1 ± 0.13); 20 seeds of
    noise alone give no line at the finder's 1e-3 (expected 0.02)."""
    z = []
    for seed in range(30):
        (ln,) = find_periodic_lines(_windows(np.random.default_rng(seed), 6e-4, 7.3, 0.1 * seed), FS)
        z.append((ln.amplitude[0] - 6e-4) / ln.amplitude_sigma[0])
    assert 0.65 < float(np.sqrt(np.mean(np.square(z)))) < 1.35
    assert (
        sum(
            bool(find_periodic_lines(_windows(np.random.default_rng(500 + s), 0.0, 1.0, 0.0), FS))
            for s in range(20)
        )
        == 0
    )


def _ar1(rng: np.random.Generator, n: int, phi: float, sd: float) -> np.ndarray:
    e = rng.standard_normal((n, 3)) * sd
    x = np.zeros((n, 3))
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


def _motion(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(n) / FS
    th = np.column_stack([2 * np.pi * t / 30.0 * 3, 1.2 * np.sin(2 * np.pi * t / 12.0), np.zeros(n)])
    f = 9.8 * np.column_stack(
        [np.sin(th[:, 1]) * np.sin(th[:, 0]), np.sin(th[:, 1]) * np.cos(th[:, 0]), np.cos(th[:, 1])]
    )
    return t, th, f


def test_angle_harmonic_is_found_beside_coloured_noise_and_bias_and_k() -> None:
    n = 9000
    _, th, f = _motion(n)
    rng = np.random.default_rng(3)
    r = _ar1(rng, n, 0.5, 2e-4) + 1e-3 * f  # what K absorbs is estimated again beside it
    r[:, 1] += 3e-4 * np.sin(2 * th[:, 0] + 0.4)
    (h,) = search_harmonics(r, f, th)
    assert (h.axis, h.harmonic, h.channels) == (0, 2, (1,))
    assert abs(h.amplitude[1] - 3e-4) < 3 * h.amplitude_sigma[1]
    assert not search_harmonics(_ar1(rng, n, 0.5, 2e-4), f, th)


def test_clock_drift_rate_and_its_sigma() -> None:
    """ρ recovered within 3 sigma; without drift, 20 seeds give z with RMS in [0.6, 1.4] and no claim
    at 1e-3 (expected 0.02)."""
    n = 9000
    t, _, f = _motion(n)
    K = np.diag([0.0177, 0.0175, 0.0179])
    kfdot = np.gradient(f, t, axis=0) @ K.T
    rho = 2e-5
    r = _ar1(np.random.default_rng(4), n, 0.8, 1e-4) - kfdot * (rho * t)[:, None]
    cd = clock_drift(r, f, kfdot, t)
    assert drift_passes(cd) and abs(cd.rate_s_per_s - rho) < 3 * cd.sigma
    z, claims = [], 0
    for seed in range(20):
        cd0 = clock_drift(_ar1(np.random.default_rng(100 + seed), n, 0.8, 1e-4), f, kfdot, t)
        z.append(cd0.rate_s_per_s / cd0.sigma)
        claims += drift_passes(cd0)
    assert claims == 0 and 0.6 < float(np.sqrt(np.mean(np.square(z)))) < 1.4


def test_families_found_together_and_taken_out_of_the_samples() -> None:
    """A 3e-4 harmonic (axis 1, twice per turn, channel y) and a 5e-5 s/s growth of the delay beside
    AR(1) noise, a mean delay and bias/K: both found, ρ within 3σ, and what ``signal`` takes out
    leaves neither (the growth re-estimated within 3σ of 0, no harmonic)."""
    n = 9000
    t, th, f = _motion(n)
    K = np.diag([0.0177, 0.0175, 0.0179])
    kfdot = np.gradient(f, t, axis=0) @ K.T
    rho, d0 = 5e-5, 2e-3
    r = _ar1(np.random.default_rng(5), n, 0.5, 1e-4) + 1e-3 * f - kfdot * (d0 + rho * t)[:, None]
    r[:, 1] += 3e-4 * np.sin(2 * th[:, 0] + 0.4)
    fam = find_families(r, f, kfdot, th, t)
    assert [(h.axis, h.harmonic, h.channels) for h in fam.harmonics] == [(0, 2, (1,))]
    assert fam.drift is not None and abs(fam.drift.rate_s_per_s - rho) < 3 * fam.drift.sigma
    assert fam.n_params == 3
    left = r - fam.signal(th, kfdot, t)
    again = find_families(left, f, kfdot, th, t)
    assert not again.harmonics and again.drift is None
    cd = clock_drift(left, f, kfdot, t)
    assert abs(cd.rate_s_per_s) < 3 * cd.sigma


def test_last_move_sign_by_hand() -> None:
    t = np.arange(12, dtype=float) * 0.1
    q = np.array([0, 0, 1, 2, 2, 2, 2, 1, 0, 0, 0, 0], dtype=float)[:, None]
    # windows start at samples 0, 4 (after the positive move), 9 (after the negative move)
    assert last_move_sign(np.deg2rad(q * 10), t, [0, 4, 9])[:, 0].tolist() == [0.0, 1.0, -1.0]
    # a count's flicker at rest (1e-4 deg per 0.1 s) is not a move
    flick = np.deg2rad(q * 10 + 1e-4 * (np.arange(12) % 2)[:, None])
    assert last_move_sign(flick, t, [0, 4, 9])[:, 0].tolist() == [0.0, 1.0, -1.0]
