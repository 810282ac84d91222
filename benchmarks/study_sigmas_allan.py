"""Allan noise-term sigmas against the spread between independent recordings of one sensor.

One simulated sensor: white noise N, a first-order Gauss–Markov bias (level σ_gm, correlation
time T_c: not one of the five IEEE 952 power laws), rate random walk K; ``seeds`` independent
recordings, three channels each. For each term: the spread (sd) of the estimates over all
recordings and channels, the median stated sigma, and their ratio (1 when the sigmas are
honest). Also the line finder on the same records with a 0.5 Hz and a 23.4 Hz line added:
how often both are found, and the same spread/sigma ratios after their removal.

    python -m benchmarks.study_sigmas_allan [seeds] [seconds]
"""

from __future__ import annotations

import math
import sys

import numpy as np
from scipy.signal import lfilter

from bench.estimation.allan import overlapping_allan
from bench.estimation.noise_terms import fit_noise_model, slope_method
from bench.estimation.spectral_lines import find_lines, remove_lines

FS_HZ = 100.0
N_WHITE, K_RRW = 1e-3, 2e-5
GM_LEVEL, GM_TC_S = 3e-4, 30.0


def record(seed: int, n: int, lines: bool) -> np.ndarray:
    """(n, 3) static record of the study's sensor."""
    rng = np.random.default_rng(seed)
    a = math.exp(-1.0 / (FS_HZ * GM_TC_S))
    gm = lfilter([1.0], [1.0, -a], rng.normal(size=(n, 3)) * GM_LEVEL * math.sqrt(1 - a * a), axis=0)
    y = N_WHITE * math.sqrt(FS_HZ) * rng.normal(size=(n, 3)) + gm
    y += np.cumsum(K_RRW / math.sqrt(FS_HZ) * rng.normal(size=(n, 3)), axis=0)
    if lines:
        t = np.arange(n) / FS_HZ
        y[:, 0] += 0.01 * np.sin(2 * np.pi * 0.5 * t + 1.0)
        y[:, 1] += 0.005 * np.sin(2 * np.pi * 23.4 * t)
    return np.asarray(y)


def study(seeds: int = 8, seconds: float = 3000.0, lines: bool = False) -> dict[str, float]:
    """Spread / median sigma per term (and the line detection rate when ``lines``)."""
    n = int(seconds * FS_HZ)
    rows, found = [], 0
    for seed in range(seeds):
        y = record(seed, n, lines)
        if lines:
            got = find_lines(y, FS_HZ)
            found += {(ln.channel, round(ln.frequency_hz, 1)) for ln in got} == {(0, 0.5), (1, 23.4)}
            y, _ = remove_lines(y, FS_HZ, got)
        r = overlapping_allan(y, FS_HZ)
        for f, s in zip(fit_noise_model(r), slope_method(r), strict=True):
            rows.append(
                [
                    f.white_n, f.white_n_sigma, f.bias_instability_b, f.bias_instability_b_sigma,
                    f.rate_random_walk_k, f.rate_random_walk_k_sigma, s.white_n, s.white_n_sigma,
                ]
            )  # fmt: skip
    a = np.array(rows)
    out = {
        name: float(a[:, i].std(ddof=1) / np.median(a[:, i + 1]))
        for name, i in (("N_fit", 0), ("B_fit", 2), ("K_fit", 4), ("N_slope", 6))
    }
    if lines:
        out["lines_found_rate"] = found / seeds
    return out


if __name__ == "__main__":
    s = int(sys.argv[1]) if len(sys.argv) > 1 else 8
    sec = float(sys.argv[2]) if len(sys.argv) > 2 else 3000.0
    print("no lines:", study(s, sec))
    print("with lines:", study(s, sec, lines=True))
