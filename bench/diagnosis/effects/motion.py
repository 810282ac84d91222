"""Effects that need the table to turn while the sensor is recorded.

``lever_arm`` and ``proof_mass_offsets`` produce centripetal ω×(ω×r) and tangential ω̇×r
terms, ``time_skew`` and ``sensor_lowpass`` matter only where the specific force changes.
In a static window ω = ω̇ = ḟ = 0, so a diagnosis of static windows cannot see them: they
are reported as not observable, with the motion the recording did contain (the moves
between windows would show them only through the dynamic model of a moving recording).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.diagnosis.effects.base import Candidate, EffectKind, ParamSpec
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


@dataclass(frozen=True)
class MotionEffect:
    """An effect that only rotation (or a changing input) reveals."""

    id: str
    parameters: tuple[ParamSpec, ...]
    explanation: str
    needs: str
    kind: EffectKind = "motion"
    needs_table: bool = True

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        base = f"needs {self.needs}; in the static windows the table stands still"
        if ev.peak_rate_rad_s > 0:
            return False, (
                f"{base} (the moves between windows, up to {np.rad2deg(ev.peak_rate_rad_s):.0f} °/s, "
                "would show it only through a dynamic model of the moving samples)"
            )
        return False, base

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        return []


LEVER_ARM = MotionEffect(
    "lever_arm",
    (ParamSpec("r_m", "m", (3,)),),
    "the sensor sits off the point where the table axes meet, so turning adds centripetal "
    "and tangential acceleration proportional to its distance",
    "rotation (ω² r of the centripetal term, ω̇ r of the tangential one)",
)
PROOF_MASS = MotionEffect(
    "proof_mass_offsets",
    (ParamSpec("rho_m", "m", (3, 3)),),
    "each axis's proof mass sits at its own place inside the unit (size effect), so each "
    "axis feels a slightly different centripetal acceleration",
    "rotation, with the unit at several orientations about the rate axis",
)
TIME_SKEW = MotionEffect(
    "time_skew",
    (ParamSpec("delay_s", "s", ()),),
    "the DAQ samples and the encoder readings are not taken at the same instant, so while "
    "the table turns the sample is matched to the wrong attitude",
    "a changing attitude during the recorded samples",
)
LOWPASS = MotionEffect(
    "sensor_lowpass",
    (ParamSpec("tau_s", "s", ()),),
    "the sensor or DAQ filter lags fast changes of the input (first-order low-pass)",
    "a specific force that changes during the recorded samples",
)
