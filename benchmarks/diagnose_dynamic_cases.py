"""Concealed-effect scenarios for ``calbench diagnose`` on moving-table recordings.

A typical ADXL-like triad (``SensorTruth.typical``, V, 100 Hz, bias wander included) on the
90 s two-axis oscillation (``simulate_oscillation``) or the rate-1axis run to ±200 °/s
(``simulate_rate_steps``), sidecar lever arm zero. Limits (measured, docs/diagnose.md):
gate × sigma of the estimate on the clean oscillation, gate = √χ²_q(1 − 0.01/5)
(q = 3 for the lever arm, 1 for the delay).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from api.simulated_recording import to_recording
from bench.diagnosis import Diagnosis
from bench.recording import Recording
from drivers.sim.offline import DEFAULT_AXES, simulate_oscillation, simulate_rate_steps
from drivers.sim.physics import SensorPhysics, SensorTruth


def moving_recording(effects: dict[str, dict[str, Any]], seed: int, kind: str = "oscillation") -> Recording:
    """A simulated oscillation-2axis (90 s) or rate-1axis recording at 100 Hz with ``effects``."""
    truth = SensorTruth.typical("V", seed=seed).with_effects(effects)
    physics = SensorPhysics(truth, DEFAULT_AXES, seed=seed)
    if kind == "oscillation":
        run = simulate_oscillation(physics, 100.0)
    elif kind == "rate":
        run = simulate_rate_steps(physics, 100.0)
    else:
        raise ValueError(f"unknown kind {kind!r}: oscillation or rate")
    return to_recording(run, serial=f"SIM-DYN-{seed}")


@dataclass(frozen=True)
class DynamicCase:
    """One motion effect at its measured limit; ``finding`` is the effect id reported."""

    effect: str
    limit: float
    unit: str
    truth: tuple[float, ...]
    finding: str
    parameter: str

    def effects(self, size: float) -> dict[str, dict[str, Any]]:
        """The truth parameters at ``size`` (direction ``truth``, scaled to ``size``)."""
        v = size * np.asarray(self.truth)
        name = {"lever_arm": "r_m", "time_skew": "delay_s", "sensor_lowpass": "tau_s"}[self.effect]
        return {self.effect: {name: v.tolist() if v.size > 1 else float(v[0])}}


DYNAMIC_CASES: dict[str, DynamicCase] = {
    c.effect: c
    for c in (
        DynamicCase("lever_arm", 3.0e-3, "m", (0.6, -0.48, 0.64), "lever_arm", "r_m"),
        DynamicCase("time_skew", 1.0e-4, "s", (1.0,), "time_skew", "delay_s"),
        DynamicCase("sensor_lowpass", 1.0e-4, "s", (1.0,), "time_skew", "delay_s"),
    )
}


def dynamic_z(case: DynamicCase, d: Diagnosis, size: float) -> float | None:
    """Largest |estimate − truth| / sigma of the reported parameter, ``None`` if not found."""
    f = next((f for f in d.findings if f.effect == case.finding), None)
    if f is None:
        return None
    est = np.atleast_1d(np.asarray(f.parameters[case.parameter], dtype=float))
    sig = np.atleast_1d(np.asarray(f.sigma[case.parameter], dtype=float))
    tru = size * np.asarray(case.truth)
    return float(np.max(np.abs(est - tru) / sig))
