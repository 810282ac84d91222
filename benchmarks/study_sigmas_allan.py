"""Allan noise-term sigmas against the spread between independent recordings of one sensor.

One simulated sensor: white noise N, a first-order Gauss–Markov bias (level σ_gm, correlation
time T_c: not one of the five IEEE 952 power laws), rate random walk K; ``seeds`` independent
recordings, three channels each. For each term of the 5-term fit (and N of the slope reading):

* ``pair_z``: RMS over all pairs of recordings of |a − b| / √(σ_a² + σ_b²), the comparison
  two recordings of one sensor make; 1 when the sigmas are honest, whatever their spread
  from recording to recording;
* ``spread``: sd of the estimates / median stated sigma. Also 1 when honest *and* the sigmas
  are alike; a few recordings with a much larger sigma (those where the model allowance
  applies) move their estimates by that much and raise it although each is covered.

Also the line finder on the same records with a 0.5 Hz and a 23.4 Hz line added: how often
both are found, and the same ratios after their removal.

    python -m benchmarks.study_sigmas_allan [seeds] [seconds[,seconds…]] [lines]
"""

from __future__ import annotations

import math
import sys

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

from bench.estimation.allan import overlapping_allan
from bench.estimation.noise_terms import fit_noise_model, slope_method
from bench.estimation.spectral_lines import find_lines, remove_lines

FS_HZ = 100.0
N_WHITE, K_RRW = 1e-3, 2e-5
GM_LEVEL, GM_TC_S = 3e-4, 30.0
TERMS = ("N_fit", "B_fit", "K_fit", "N_slope")


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


def pair_z_rms(values: npt.ArrayLike, sigmas: npt.ArrayLike) -> float:
    """RMS over all pairs i < j of (v_i − v_j) / √(σ_i² + σ_j²)."""
    v, s = np.asarray(values, dtype=float), np.asarray(sigmas, dtype=float)
    i, j = np.triu_indices(v.size, 1)
    return float(np.sqrt(np.mean((v[i] - v[j]) ** 2 / (s[i] ** 2 + s[j] ** 2))))


def estimates(seeds: int, seconds: float, lines: bool = False) -> tuple[np.ndarray, int]:
    """((seeds·3, 8) [value, sigma] of N, B, K (fit) and N (slope) per channel, line successes)."""
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
    return np.array(rows), found


def study(seeds: int = 8, seconds: float = 3000.0, lines: bool = False) -> dict[str, float]:
    """``pair_z`` and ``spread`` per term (see module doc), and the line detection rate when ``lines``."""
    a, found = estimates(seeds, seconds, lines)
    out: dict[str, float] = {}
    for k, name in enumerate(TERMS):
        v, s = a[:, 2 * k], a[:, 2 * k + 1]
        out[f"{name}_pair_z"] = pair_z_rms(v, s)
        out[f"{name}_spread"] = float(v.std(ddof=1) / np.median(s))
    if lines:
        out["lines_found_rate"] = found / seeds
    return out


def _show(label: str, res: dict[str, float]) -> str:
    return label + "  " + "  ".join(f"{k} {v:.2f}" for k, v in res.items())


if __name__ == "__main__":
    s = int(sys.argv[1]) if len(sys.argv) > 1 else 8
    lengths = [float(x) for x in sys.argv[2].split(",")] if len(sys.argv) > 2 else [3000.0]
    with_lines = len(sys.argv) > 3 and sys.argv[3] == "lines"
    for sec in lengths:
        print(_show(f"{sec:g} s, no lines:", study(s, sec)))
        if with_lines:
            print(_show(f"{sec:g} s, with lines:", study(s, sec, lines=True)))
