"""Typed effects: each says how it enters the model and whether its physics is the table's."""

from __future__ import annotations

from typing import get_args

from bench.diagnosis.effects import EFFECTS, NEEDS_TABLE, EffectKind


def test_every_effect_has_a_kind_of_the_four() -> None:
    assert {e.kind for e in EFFECTS} <= set(get_args(EffectKind))
    kinds = {e.id: e.kind for e in EFFECTS}
    assert kinds["pose_error"] == "variance"
    assert kinds["settling"] == "window"
    assert kinds["lever_arm"] == kinds["time_skew"] == "motion"
    assert kinds["nonlinearity_quadratic"] == kinds["table_tilt"] == "columns"


def test_needs_table_is_the_tables_physics() -> None:
    # the table's motion, encoders, base and ringing after a move; a sensor's own effects and a
    # pose error (the unit not where the recording says) do not need one
    assert {
        "lever_arm",
        "proof_mass_offsets",
        "time_skew",
        "table_tilt",
        "encoder_offset",
        "sensor_lowpass",
        "settling",
        "table_axis_error",
        "hysteresis",
    } == NEEDS_TABLE
    assert all(isinstance(e.needs_table, bool) for e in EFFECTS)
