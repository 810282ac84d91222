"""K and bias z-scores of the static-12 window fit against pose order, duration and wander.

The bench's static-12 poses (``bench.procedures.static``) in their execution order (antipodes
one after the other) or in the icosahedron's ring order (+z first, −z last, the former order),
simulated by ``drivers/sim`` for ``SensorTruth.typical`` (250 µg/√Hz, 40 µg / 200 s wander,
optionally a bias random walk) and fitted by ``calibrate_recording`` (window means, known
orientations). Per case: RMS of the K z-scores against the truth (9 per seed), of the bias
against the run's mean and the long-run bias, the largest |z|.

    python -m benchmarks.study_sigmas_static ORDER DWELL_S SEEDS [RANDOM_WALK]

ORDER ``bench`` or ``ring``; the run lasts about 12 × (DWELL_S + 6) s.
"""

from __future__ import annotations

import dataclasses
import sys

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration import calibrate_recording
from bench.procedures.static import icosahedron_up_directions, pose_for_up, static_12_poses_deg
from drivers.sim.offline import DEFAULT_AXES, simulate_static
from drivers.sim.physics import SensorPhysics
from drivers.sim.sensor_truth import SensorTruth


def poses(order: str) -> np.ndarray:
    """(12, 3) table angles (deg) in the order visited."""
    if order == "bench":
        return np.array(static_12_poses_deg())
    if order == "ring":
        outer = (0.0, 90.0, 180.0, -90.0)
        return np.array([pose_for_up(d, outer[i % 4]) for i, d in enumerate(icosahedron_up_directions())])
    raise ValueError(f"order must be 'bench' or 'ring', got {order!r}")


def z_scores(order: str, dwell_s: float, seed: int, random_walk: float = 0.0) -> dict[str, np.ndarray]:
    """z of K (9), of the bias against the run's mean (3) and against the long-run bias (3)."""
    tr = SensorTruth.typical("V", seed=seed)
    if random_walk:
        tr = dataclasses.replace(
            tr, noise=dataclasses.replace(tr.noise, random_walk_m_s2_s_rt_hz=random_walk)
        )
    run = simulate_static(poses(order), dwell_s, SensorPhysics(tr, DEFAULT_AXES, seed=2000 + seed), 100.0)
    res = calibrate_recording(to_recording(run, serial="SN-STUDY"))
    return {
        "K": ((res.K - tr.K) / res.K_sigma).ravel(),
        "bias_run": (res.bias - run.bias_seen()) / res.bias_sigma,
        "bias_long": (res.bias - tr.bias) / res.bias_sigma,
        "minutes": np.array([run.t_s[-1] / 60.0]),
    }


def study(order: str, dwell_s: float, seeds: int, random_walk: float = 0.0) -> dict[str, float]:
    """RMS z per group and the largest |z| of K and bias (run mean)."""
    out = [z_scores(order, dwell_s, s, random_walk) for s in range(seeds)]
    rms = {
        k: float(np.sqrt(np.mean(np.concatenate([o[k] for o in out]) ** 2)))
        for k in ("K", "bias_run", "bias_long")
    }
    return {
        "minutes": float(out[0]["minutes"][0]),
        **{f"rms_z_{k}": v for k, v in rms.items()},
        "max_abs_z": float(max(np.max(np.abs(np.r_[o["K"], o["bias_run"]])) for o in out)),
    }


if __name__ == "__main__":
    o, d, n = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
    rw = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
    print(o, d, n, rw, {key: round(v, 3) for key, v in study(o, d, n, rw).items()})
