"""Allan noise-term sigmas against the spread between independent recordings of one sensor.

Three simulated sensors, ``seeds`` independent recordings of three channels each, fitted by
the 5-term fit (and N also by the slope reading):

* ``gm``: this study's own generator, from the noise definitions: white noise N, a
  first-order Gauss–Markov bias (level σ_gm, correlation time T_c: not one of the five
  IEEE 952 power laws), rate random walk K;
* ``sim``: the same noise from calbench's simulator (``drivers.sim.noise.NoiseStream``);
* ``powerlaw``: white N, flicker B and rate random walk K only, so the terms have a truth;
* ``whiterw``: white N and rate random walk K alone (no Gauss–Markov bias, no flicker).
  Flicker is a sum of first-order Gauss–Markov processes with correlation times half an
  octave apart, each of variance c: Σ 4cT_j/(1 + (2πfT_j)²) → (c/ln r)/f for spacing r
  (Keshner, Proc. IEEE 70, 1982), so h₋₁ = c/ln r and B² = π·h₋₁ (IEEE 952 Table C.2) —
  a construction independent of the spectral shaping in ``tests.support.noise``.

Measures per term:

* ``pair_z``: RMS over all pairs of recordings of |a − b| / √(σ_a² + σ_b²), the comparison
  two recordings of one sensor make; 1 when the sigmas are honest, whatever their spread
  from recording to recording;
* ``spread``: sd of the estimates / median stated sigma;
* ``truth_z`` (``powerlaw``, ``whiterw``; N and K also on ``gm`` and ``sim``, whose N and K are
  the injected ones): RMS of (estimate − truth) / sigma, and ``truth_2s`` the share within 2σ;
* the Gauss–Markov term: ``GM_admitted`` the share of curves whose fit admits it (the
  false-admission rate on ``powerlaw`` and ``whiterw``), and on ``gm`` and ``sim`` among those
  admitted ``GM_level_truth_z`` / ``GM_tc_truth_z`` (T_c's z in ln T_c, its sigma linearised)
  and the shares within 2σ, and the pair z of σ_gm and ln T_c.

Also the line finder on the ``gm`` records with a 0.5 Hz and a 23.4 Hz line added: how often
both are found, and the same ratios after their removal.

    python -m benchmarks.study_sigmas_allan [seeds] [seconds[,…]] [gm|sim|powerlaw|whiterw|lines|real][,…]
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

from bench.estimation.allan import overlapping_allan
from bench.estimation.noise_terms import fit_noise_model, slope_method
from bench.estimation.spectral_lines import find_lines, remove_lines
from drivers.sim.noise import NoiseSpec, NoiseStream

FS_HZ = 100.0
N_WHITE, K_RRW = 1e-3, 2e-5
GM_LEVEL, GM_TC_S = 3e-4, 30.0
B_FLICKER = 2e-4
TERMS = ("N_fit", "B_fit", "K_fit", "N_slope")
SENSORS = ("gm", "sim", "powerlaw", "whiterw")
GM_SENSORS = ("gm", "sim")


def _gauss_markov(rng: np.random.Generator, n: int, level: float, tc_s: float) -> np.ndarray:
    """(n, 3) stationary first-order Gauss–Markov process of standard deviation level."""
    a = math.exp(-1.0 / (FS_HZ * tc_s))
    drive = rng.normal(size=(n, 3)) * level * math.sqrt(1 - a * a)
    drive[0] = rng.normal(size=3) * level
    return np.asarray(lfilter([1.0], [1.0, -a], drive, axis=0))


def record(seed: int, n: int, lines: bool, sensor: str = "gm") -> np.ndarray:
    """(n, 3) static record of the study's sensor ``sensor`` (see module doc)."""
    rng = np.random.default_rng(seed)
    if sensor == "sim":
        spec = NoiseSpec(
            white_m_s2_rt_hz=N_WHITE,
            bias_instability_m_s2=GM_LEVEL,
            bias_instability_tau_s=GM_TC_S,
            random_walk_m_s2_s_rt_hz=K_RRW,
        )
        white, wander = NoiseStream(spec, rng, FS_HZ).next(np.arange(n) / FS_HZ)
        return np.asarray(white + wander)
    if sensor not in SENSORS:
        raise ValueError(f"unknown sensor {sensor!r}; known: {SENSORS}")
    a = math.exp(-1.0 / (FS_HZ * GM_TC_S))
    gm = lfilter([1.0], [1.0, -a], rng.normal(size=(n, 3)) * GM_LEVEL * math.sqrt(1 - a * a), axis=0)
    y = N_WHITE * math.sqrt(FS_HZ) * rng.normal(size=(n, 3)) + (gm if sensor == "gm" else 0.0)
    # gm is drawn on every sensor, so a seed's white and random walk are the same on each
    y += np.cumsum(K_RRW / math.sqrt(FS_HZ) * rng.normal(size=(n, 3)), axis=0)
    if sensor == "powerlaw":
        y += _flicker(rng, n)
    if lines:
        t = np.arange(n) / FS_HZ
        y[:, 0] += 0.01 * np.sin(2 * np.pi * 0.5 * t + 1.0)
        y[:, 1] += 0.005 * np.sin(2 * np.pi * 23.4 * t)
    return np.asarray(y)


def _flicker(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3) flicker of coefficient B_FLICKER: Gauss–Markov processes half an octave apart (module doc)."""
    ratio = math.sqrt(2.0)
    level = B_FLICKER * math.sqrt(math.log(ratio) / math.pi)
    out = np.zeros((n, 3))
    tc = 1.0 / FS_HZ
    while tc < 30.0 * n / FS_HZ:
        a = math.exp(-1.0 / (FS_HZ * tc))
        drive = rng.normal(size=(n, 3)) * level * math.sqrt(1 - a * a)
        drive[0] = rng.normal(size=3) * level  # stationary start
        out += lfilter([1.0], [1.0, -a], drive, axis=0)
        tc *= ratio
    return out


def pair_z_rms(values: npt.ArrayLike, sigmas: npt.ArrayLike) -> float:
    """RMS over all pairs i < j of (v_i − v_j) / √(σ_i² + σ_j²)."""
    v, s = np.asarray(values, dtype=float), np.asarray(sigmas, dtype=float)
    i, j = np.triu_indices(v.size, 1)
    return float(np.sqrt(np.mean((v[i] - v[j]) ** 2 / (s[i] ** 2 + s[j] ** 2))))


def estimates(seeds: int, seconds: float, lines: bool = False, sensor: str = "gm") -> tuple[np.ndarray, int]:
    """((seeds·3, 12) [value, sigma] of N, B, K (fit), N (slope), σ_gm and T_c (fit) per channel,
    line successes)."""
    n = int(seconds * FS_HZ)
    rows, found = [], 0
    for seed in range(seeds):
        y = record(seed, n, lines, sensor)
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
                    f.gauss_markov_level, f.gauss_markov_level_sigma, f.gauss_markov_tc_s,
                    f.gauss_markov_tc_s_sigma,
                ]
            )  # fmt: skip
    return np.array(rows), found


def study(
    seeds: int = 8, seconds: float = 3000.0, lines: bool = False, sensor: str = "gm"
) -> dict[str, float]:
    """``pair_z`` and ``spread`` per term (and ``truth_z`` for ``powerlaw``; module doc), and the
    line detection rate when ``lines``."""
    a, found = estimates(seeds, seconds, lines, sensor)
    truth = {"N_fit": N_WHITE, "B_fit": B_FLICKER, "K_fit": K_RRW, "N_slope": N_WHITE}
    if sensor == "whiterw":
        truth["B_fit"] = 0.0
    out: dict[str, float] = {}
    for k, name in enumerate(TERMS):
        v, s = a[:, 2 * k], a[:, 2 * k + 1]
        out[f"{name}_pair_z"] = pair_z_rms(v, s)
        out[f"{name}_spread"] = float(v.std(ddof=1) / np.median(s))
        if sensor in ("powerlaw", "whiterw") or (sensor in GM_SENSORS and name != "B_fit"):
            z = (v - truth[name]) / s
            out[f"{name}_truth_z"] = float(np.sqrt(np.mean(z**2)))
            out[f"{name}_truth_2s"] = float(np.mean(np.abs(z) <= 2.0))
    level, level_s, tc, tc_s = a[:, 8], a[:, 9], a[:, 10], a[:, 11]
    admitted = level > 0.0
    out["GM_admitted"] = float(np.mean(admitted))
    out["GM_admitted_of"] = float(admitted.size)
    out["GM_admitted_n"] = float(admitted.sum())
    if sensor in GM_SENSORS and admitted.sum() > 1:
        z_level = (level[admitted] - GM_LEVEL) / level_s[admitted]
        z_tc = np.log(tc[admitted] / GM_TC_S) / (tc_s[admitted] / tc[admitted])
        out["GM_level_truth_z"] = float(np.sqrt(np.mean(z_level**2)))
        out["GM_level_truth_2s"] = float(np.mean(np.abs(z_level) <= 2.0))
        out["GM_tc_truth_z"] = float(np.sqrt(np.mean(z_tc**2)))
        out["GM_tc_truth_2s"] = float(np.mean(np.abs(z_tc) <= 2.0))
        out["GM_level_pair_z"] = pair_z_rms(level[admitted], level_s[admitted])
        out["GM_tc_pair_z"] = pair_z_rms(np.log(tc[admitted]), tc_s[admitted] / tc[admitted])
        out["GM_tc_median_s"] = float(np.median(tc[admitted]))
    if lines:
        out["lines_found_rate"] = found / seeds
    return out


REAL_DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "real"
"""The real data sets (tests/data/real; each folder's README says where it comes from)."""
XSENS_REST_S = (0.5, 51.9)
"""The initial rest of the IMU-TK Xsens recording (its data README: the first static interval)."""


def real_split(data_dir: Path, parts: int = 4) -> dict[str, float]:
    """``pair_z`` of N, B, K between ``parts`` disjoint pieces of the real Xsens rest.

    ``imu_tk-xsens`` (100 Hz, raw counts): the accelerometer and gyro channels of the 52 s
    initial rest cut into ``parts`` equal pieces; every pair of pieces of one channel is a
    comparison (6 channels × parts·(parts − 1)/2 pairs).
    """
    d = data_dir / "imu_tk-xsens"
    acc, gyr = (np.loadtxt(d / name) for name in ("xsens_acc.mat", "xsens_gyro.mat"))
    keep = (acc[:, 0] >= XSENS_REST_S[0]) & (acc[:, 0] < XSENS_REST_S[1])
    y = np.column_stack([acc[keep, 1:], gyr[keep, 1:]])
    size = y.shape[0] // parts
    rows = []
    for k in range(parts):
        fits = fit_noise_model(overlapping_allan(y[k * size : (k + 1) * size], FS_HZ))
        rows.append([[f.white_n, f.white_n_sigma, f.bias_instability_b, f.bias_instability_b_sigma,
                      f.rate_random_walk_k, f.rate_random_walk_k_sigma] for f in fits])  # fmt: skip
    a = np.array(rows)  # (parts, channels, 6)
    i, j = np.triu_indices(parts, 1)
    out: dict[str, float] = {}
    for k, name in enumerate(("N_fit", "B_fit", "K_fit")):
        v, s = a[:, :, 2 * k], a[:, :, 2 * k + 1]
        z2 = (v[i] - v[j]) ** 2 / (s[i] ** 2 + s[j] ** 2)
        out[f"{name}_pair_z"] = float(np.sqrt(np.mean(z2)))
    out["pairs"] = float(z2.size)
    return out


def _show(label: str, res: dict[str, float]) -> str:
    return label + "  " + "  ".join(f"{k} {v:.2f}" for k, v in res.items())


if __name__ == "__main__":
    s = int(sys.argv[1]) if len(sys.argv) > 1 else 8
    lengths = [float(x) for x in sys.argv[2].split(",")] if len(sys.argv) > 2 else [3000.0]
    kinds = sys.argv[3].split(",") if len(sys.argv) > 3 else ["gm"]
    if kinds == ["real"]:
        for parts in (2, 4):
            print(_show(f"Xsens rest in {parts} parts:", real_split(REAL_DATA, parts)))
        sys.exit(0)
    for sec in lengths:
        for kind in kinds:
            if kind == "lines":
                print(_show(f"{sec:g} s, gm, no lines:", study(s, sec)))
                print(_show(f"{sec:g} s, gm, with lines:", study(s, sec, lines=True)))
            else:
                print(_show(f"{sec:g} s, {kind}:", study(s, sec, sensor=kind)), flush=True)
