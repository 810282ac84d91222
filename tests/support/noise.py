"""Noise generators with known Allan deviations (IEEE 952, NIST SP 1065), for tests of the
noise-term fit, the dwell rule and the allan command."""

from __future__ import annotations

import math

import numpy as np


def white(rng: np.random.Generator, n: int, fs_hz: float, N: float, c: int) -> np.ndarray:
    """(n, c) white noise of density N (u·√s): per-sample σ = N·√fs, so σ_A(τ) = N/√τ."""
    return N * math.sqrt(fs_hz) * rng.normal(size=(n, c))


def rate_random_walk(rng: np.random.Generator, n: int, fs_hz: float, K: float, c: int) -> np.ndarray:
    """(n, c) random walk y_k = Σ K/√fs·w_i: σ_A(τ) = K·√(τ/3) for τ ≫ 1/fs."""
    return np.cumsum(K / math.sqrt(fs_hz) * rng.normal(size=(n, c)), axis=0)


def flicker(rng: np.random.Generator, n: int, fs_hz: float, B: float, c: int) -> np.ndarray:
    """(n, c) flicker noise, one-sided PSD h/f with h = B²/π, by spectral shaping.

    SP1065 Table 2: σ²_A = 2 ln2 · h = (2 ln2/π)·B² = (0.664·B)², the IEEE 952 floor, for
    τ between a few samples and about a tenth of the record.
    """
    f = np.fft.rfftfreq(n, 1.0 / fs_hz)
    amp = np.zeros_like(f)
    amp[1:] = np.sqrt(B**2 / math.pi / f[1:] * fs_hz * n / 2.0)
    spectrum = (rng.normal(size=(f.size, c)) + 1j * rng.normal(size=(f.size, c))) / math.sqrt(2.0)
    return np.fft.irfft(spectrum * amp[:, None], n, axis=0)
