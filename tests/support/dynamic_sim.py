"""Simulated moving-table runs for the dynamic-calibration tests (truth from drivers.sim)."""

from __future__ import annotations

from typing import Any

import numpy as np

from api.simulated_recording import to_recording
from bench.recording import Recording
from drivers.sim.noise import NoiseSpec
from drivers.sim.offline import DEFAULT_AXES, SimulatedRun, simulate_oscillation, simulate_rate_steps
from drivers.sim.physics import SensorPhysics, SensorTruth

R_TRUE_M = np.array([0.05, -0.02, 0.03])
TILT_TRUE_RAD = np.array([2e-4, -3e-4])
DELAY_TRUE_S = 2e-3
EFFECTS: dict[str, dict[str, Any]] = {
    "lever_arm": {"r_m": R_TRUE_M.tolist()},
    "table_tilt": {"tilt_rad": TILT_TRUE_RAD.tolist()},
    "time_skew": {"delay_s": DELAY_TRUE_S},
}


def truth(
    seed: int = 3, effects: dict[str, dict[str, Any]] | None = None, noiseless: bool = False
) -> SensorTruth:
    """An ADXL325-like unit (volts) with the given effects (default :data:`EFFECTS`)."""
    tr = SensorTruth.typical("V", seed=seed).with_effects(EFFECTS if effects is None else effects)
    if noiseless:
        tr = tr.with_noise(NoiseSpec(white_m_s2_rt_hz=0.0))
    return tr


def oscillation(seed: int = 1, rate_hz: float = 100.0, **kw: Any) -> tuple[SimulatedRun, Recording]:
    """The oscillation-2axis run of docs/methods.md §2 (90 s) and its recording (zero believed lever arm)."""
    tr = kw.pop("truth", None) or truth()
    run = simulate_oscillation(SensorPhysics(tr, DEFAULT_AXES, seed=seed), rate_hz, **kw)
    return run, to_recording(run, serial="SN-DYN")


def rate(seed: int = 1, rate_hz: float = 100.0, **kw: Any) -> tuple[SimulatedRun, Recording]:
    """A rate-1axis run to ±200 °/s at three poses and its recording."""
    tr = kw.pop("truth", None) or truth()
    run = simulate_rate_steps(SensorPhysics(tr, DEFAULT_AXES, seed=seed), rate_hz, **kw)
    return run, to_recording(run, serial="SN-RATE")
