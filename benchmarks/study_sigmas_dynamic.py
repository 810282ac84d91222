"""z-scores of the moving-table fits against the concealed truth, over seeds.

The bench's rate-1axis procedure (its six poses and six rates, ``bench.procedures.rate``) and
the two-axis oscillation, simulated by ``drivers/sim`` for the ADXL325-like unit of
``SensorTruth.typical`` (250 µg/√Hz white noise, a 40 µg / 200 s Gauss–Markov bias wander,
16-bit converter, 100 Hz), optionally with a bias random walk; fitted by the dynamic batch
fit with bias and K (``calibrate_dynamic``, terms declared empty). Per case: the spread of
the z-scores of K (9 per seed) against the truth, of the bias against the run's mean bias
(``bias_seen``) and against the unit's long-run bias, the median over seeds of the worst
|z| of the 12 parameters, and the largest |z|.

    python -m benchmarks.study_sigmas_dynamic KIND DURATION SEEDS [RANDOM_WALK]

KIND ``rate`` (DURATION: each rate window's dwell, s) or ``oscillation`` (DURATION: s);
RANDOM_WALK in m/s² per √s (default 0).
"""

from __future__ import annotations

import dataclasses
import sys

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration.dynamic import calibrate_dynamic
from bench.procedures.rate import DEFAULT_POSES_DEG, DEFAULT_RATES_DEG_S
from drivers.sim.offline import DEFAULT_AXES, SimulatedRun, simulate_oscillation, simulate_rate_steps
from drivers.sim.physics import SensorPhysics
from drivers.sim.sensor_truth import SensorTruth


def simulate(kind: str, duration_s: float, seed: int, random_walk: float = 0.0) -> SimulatedRun:
    """One recording of the study's unit."""
    tr = SensorTruth.typical("V", seed=seed)
    if random_walk:
        tr = dataclasses.replace(
            tr, noise=dataclasses.replace(tr.noise, random_walk_m_s2_s_rt_hz=random_walk)
        )
    ph = SensorPhysics(tr, DEFAULT_AXES, seed=1000 + seed)
    if kind == "rate":
        return simulate_rate_steps(
            ph, 100.0, rates_deg_s=DEFAULT_RATES_DEG_S, poses_deg=DEFAULT_POSES_DEG, dwell_s=duration_s
        )
    if kind == "oscillation":
        return simulate_oscillation(ph, 100.0, duration_s=duration_s)
    raise ValueError(f"kind must be 'rate' or 'oscillation', got {kind!r}")


def z_scores(kind: str, duration_s: float, seed: int, random_walk: float = 0.0) -> dict[str, np.ndarray]:
    """z of K (9), of the bias against the run's mean (3) and against the long-run bias (3)."""
    run = simulate(kind, duration_s, seed, random_walk)
    res = calibrate_dynamic(to_recording(run, serial="SN-STUDY"), terms=(), cross_check=False)
    return {
        "K": ((res.K - run.truth.K) / res.K_sigma).ravel(),
        "bias_run": (res.bias - run.bias_seen()) / res.bias_sigma,
        "bias_long": (res.bias - run.truth.bias) / res.bias_sigma,
        "minutes": np.array([run.t_s[-1] / 60.0]),
    }


def study(kind: str, duration_s: float, seeds: int, random_walk: float = 0.0) -> dict[str, float]:
    """Spread (RMS) of z per group, median worst |z| over the 12 parameters, largest |z|."""
    out = [z_scores(kind, duration_s, s, random_walk) for s in range(seeds)]
    rms = {
        k: float(np.sqrt(np.mean(np.concatenate([o[k] for o in out]) ** 2)))
        for k in ("K", "bias_run", "bias_long")
    }
    worst = [float(np.max(np.abs(np.r_[o["K"], o["bias_run"]]))) for o in out]
    return {
        "minutes": float(out[0]["minutes"][0]),
        **{f"rms_z_{k}": v for k, v in rms.items()},
        "median_worst_abs_z": float(np.median(worst)),
        "max_abs_z": float(max(worst)),
    }


if __name__ == "__main__":
    k, d, n = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
    rw = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
    print(k, d, n, rw, {key: round(v, 3) for key, v in study(k, d, n, rw).items()})
