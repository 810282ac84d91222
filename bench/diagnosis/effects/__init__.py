"""The catalogue of physical effects (``docs/cli-contract.md``), one object per effect id, in its order."""

from __future__ import annotations

from bench.diagnosis.effects.base import (
    Candidate,
    Effect,
    EffectKind,
    ParamSpec,
    first_order_design,
    leverage,
)
from bench.diagnosis.effects.geometry import ENCODER_OFFSET, POSE_ERROR, TILT, pose_response
from bench.diagnosis.effects.last_move import LAST_MOVE
from bench.diagnosis.effects.motion import LEVER_ARM, LOWPASS, PROOF_MASS, TIME_SKEW
from bench.diagnosis.effects.sensor import ASYMMETRY, CROSS_COUPLING, DRIFT, NONLINEARITY, TEMPERATURE
from bench.diagnosis.effects.settling import SETTLING
from bench.diagnosis.effects.table_axes import TABLE_AXIS_ERROR
from bench.diagnosis.effects.thermal_lag import THERMAL_LAG

CATALOGUE: tuple[Effect, ...] = (
    LEVER_ARM,
    PROOF_MASS,
    NONLINEARITY,
    ASYMMETRY,
    CROSS_COUPLING,
    TEMPERATURE,
    DRIFT,
    TIME_SKEW,
    TILT,
    POSE_ERROR,
    ENCODER_OFFSET,
    LOWPASS,
    SETTLING,
)
"""Every effect of the contract's table, in its order."""

BENCH_EFFECTS: tuple[Effect, ...] = (TABLE_AXIS_ERROR, LAST_MOVE, THERMAL_LAG)
"""Effects of the bench beyond the contract's first table (docs/diagnose.md, "Bench physics
beyond the catalogue"), searched beside it."""

WITH_LIBRARY = frozenset({"hysteresis"})
"""Effects whose candidates are searched with the term library (its share of the false-alarm
budget, once no catalogue candidate is admissible) rather than beside the catalogue: a
signature that is no function of the pose, like the library's terms beyond the catalogue."""

EFFECTS: tuple[Effect, ...] = (*CATALOGUE, *BENCH_EFFECTS)
"""Every effect a static diagnosis tries."""

BY_ID = {e.id: e for e in EFFECTS}

NEEDS_TABLE = frozenset(e.id for e in EFFECTS if e.needs_table)
"""Effects whose physics is the table's (its motion, its encoders, its base, its ringing after a
move): never a candidate on a recording without a table, whatever the data look like."""

__all__ = [
    "BENCH_EFFECTS",
    "BY_ID",
    "CATALOGUE",
    "EFFECTS",
    "NEEDS_TABLE",
    "WITH_LIBRARY",
    "Candidate",
    "Effect",
    "EffectKind",
    "ParamSpec",
    "first_order_design",
    "leverage",
    "pose_response",
]
