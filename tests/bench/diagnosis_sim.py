"""Simulated static-12 recordings with concealed catalogue effects, for the diagnosis tests."""

from __future__ import annotations

from typing import Any

from api.simulated_recording import to_recording
from bench.recording import Recording
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth


def static_recording(effects: dict[str, dict[str, Any]], seed: int, dwell_s: float = 30.0) -> Recording:
    """A typical ADXL-like triad (V, 100 Hz, bias wander included) on the 12-pose tumble."""
    truth = SensorTruth.typical("V", seed=seed).with_effects(effects)
    physics = SensorPhysics(truth, DEFAULT_AXES, seed=seed)
    run = simulate_static(static12_poses_deg(), dwell_s, physics, 100.0)
    return to_recording(run, serial=f"SIM-{seed}")
