"""Concealed-effect scenarios for ``calbench diagnose`` on moving-table recordings.

A typical ADXL-like triad (``SensorTruth.typical``, V, 100 Hz, bias wander included), sidecar
lever arm zero, on one of

- ``oscillation``: the 90 s two-axis oscillation (``simulate_oscillation``);
- ``rate``: the rate-1axis run to ±200 °/s at three poses (``simulate_rate_steps``, 73 s);
- ``rate_tilted``: ±200 °/s at four poses, three of them with the turning axis between two
  sensor axes (middle, inner) = (0, 0), (45, 0), (45, 90), (90, 45) °, 5 s windows (115 s):
  the tilted poses make every channel's centripetal term see the off-axis components of its
  own proof-mass offset (the size effect), which the three axis-aligned poses cannot.

Limits (measured, docs/diagnose.md): gate × sigma of the estimate on the clean recording,
gate = √χ²_q(1 − 0.01/N), N candidates in the step (5 in the first: q = 3 for the lever arm
and the nonlinearity, 1 for the delay; 4 in the second: q = 6 for the proof masses, which
are tried once a lever arm is in, so their scenario carries a 12 mm lever arm as well).
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

TILTED_POSES_DEG = ((0.0, 0.0), (45.0, 0.0), (45.0, 90.0), (90.0, 45.0))
"""(middle, inner) poses of the ``rate_tilted`` run (module docstring)."""
PROOF_MASS_RHO = ((1.0, -0.5, 0.3), (-0.4, 0.2, -0.8), (-0.6, 0.3, 0.5))
"""Direction of the concealed proof-mass offsets (rows x, y, z; each column sums to zero, so
the lever arm, their mean, is unchanged and the reported departures are the truth itself)."""
LEVER_FOR_PROOF_MASS_M = (0.01, -0.006, 0.004)


def moving_recording(effects: dict[str, dict[str, Any]], seed: int, kind: str = "oscillation") -> Recording:
    """A simulated moving recording at 100 Hz with ``effects`` (``kind``: module docstring)."""
    truth = SensorTruth.typical("V", seed=seed).with_effects(effects)
    physics = SensorPhysics(truth, DEFAULT_AXES, seed=seed)
    if kind == "oscillation":
        run = simulate_oscillation(physics, 100.0)
    elif kind == "rate":
        run = simulate_rate_steps(physics, 100.0)
    elif kind == "rate_tilted":
        run = simulate_rate_steps(
            physics, 100.0, rates_deg_s=(200.0, -200.0), poses_deg=TILTED_POSES_DEG, dwell_s=5.0
        )
    else:
        raise ValueError(f"unknown kind {kind!r}: oscillation, rate or rate_tilted")
    return to_recording(run, serial=f"SIM-DYN-{seed}")


@dataclass(frozen=True)
class DynamicCase:
    """One motion effect at its measured limit; ``finding`` is the effect id reported.

    ``truth`` is the direction (flattened) scaled by the size; ``kind`` the recording;
    ``extra`` effects concealed beside it at fixed size.
    """

    effect: str
    limit: float
    unit: str
    truth: tuple[float, ...]
    finding: str
    parameter: str
    kind: str = "oscillation"
    extra: tuple[tuple[str, str, tuple[float, ...]], ...] = ()

    def effects(self, size: float) -> dict[str, dict[str, Any]]:
        """The truth parameters at ``size`` (direction ``truth``, scaled to ``size``)."""
        v = size * np.asarray(self.truth)
        name = {
            "lever_arm": "r_m",
            "time_skew": "delay_s",
            "sensor_lowpass": "tau_s",
            "proof_mass_offsets": "rho_m",
            "nonlinearity_quadratic": "k2_per_g",
        }[self.effect]
        value = v.reshape(3, 3).tolist() if v.size == 9 else v.tolist() if v.size > 1 else float(v[0])
        out: dict[str, dict[str, Any]] = {self.effect: {name: value}}
        for eff, pname, val in self.extra:
            out[eff] = {pname: list(val)}
        return out

    def recording(self, size: float, seed: int) -> Recording:
        """The simulated recording with the effect at ``size``."""
        return moving_recording(self.effects(size), seed, kind=self.kind)


DYNAMIC_CASES: dict[str, DynamicCase] = {
    c.effect: c
    for c in (
        DynamicCase("lever_arm", 3.0e-3, "m", (0.6, -0.48, 0.64), "lever_arm", "r_m"),
        DynamicCase("time_skew", 1.0e-4, "s", (1.0,), "time_skew", "delay_s"),
        DynamicCase("sensor_lowpass", 1.0e-4, "s", (1.0,), "time_skew", "delay_s"),
        DynamicCase(
            "nonlinearity_quadratic", 2.5e-4, "1/g", (0.0, 0.0, 1.0), "nonlinearity_quadratic", "k2_per_g"
        ),
        DynamicCase(
            "proof_mass_offsets",
            3.5e-4,
            "m",
            tuple(np.ravel(PROOF_MASS_RHO)),
            "proof_mass_offsets",
            "rho_m",
            kind="rate_tilted",
            extra=(("lever_arm", "r_m", LEVER_FOR_PROOF_MASS_M),),
        ),
    )
}
"""Moving-recording cases; limits of docs/diagnose.md (largest proof-mass component for
``proof_mass_offsets``, the z channel's k2 for the nonlinearity)."""


def dynamic_z(case: DynamicCase, d: Diagnosis, size: float) -> float | None:
    """Largest |estimate − truth| / sigma of the reported parameter, ``None`` if not found."""
    f = next((f for f in d.findings if f.effect == case.finding), None)
    if f is None:
        return None
    est = np.ravel(np.asarray(f.parameters[case.parameter], dtype=float))
    sig = np.ravel(np.asarray(f.sigma[case.parameter], dtype=float))
    tru = size * np.asarray(case.truth)
    return float(np.max(np.abs(est - tru) / sig))
