"""``calbench simulate``: write a simulated recording with chosen effects.

Example::

    calbench simulate --procedure static-12 --effect nonlinearity_quadratic:k2_per_g=0,0,1.5e-3 \\
        --seed 7 -o run.csv

writes ``run.csv``, ``run.json`` (the sidecar: what the bench believes) and
``run.truth.json`` (the unit's true bias, K, effects and noise).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Any

import numpy as np

from api.cli import BadInput, decimal_arg
from api.simulated_recording import nominal_geometry, write_simulated
from drivers.sim.noise import NoiseSpec
from drivers.sim.offline import (
    DEFAULT_AXES,
    SimulatedRun,
    simulate_oscillation,
    simulate_rate_steps,
    simulate_static,
    static12_poses_deg,
)
from drivers.sim.physics import SensorPhysics
from drivers.sim.sensor_truth import EFFECT_PARAMETERS, SensorTruth

PROCEDURES = ("static-12", "rate-1axis", "oscillation-2axis")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``calbench simulate``."""
    parser.add_argument("--procedure", choices=PROCEDURES, default="static-12")
    parser.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="ID:PARAM=V1,V2,...",
        help=f"add a catalogue effect (repeatable); ids: {', '.join(EFFECT_PARAMETERS)}",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the noise (default 0)")
    parser.add_argument(
        "--unit-seed", type=int, default=None, help="seed of the unit's bias and K (default: --seed)"
    )
    parser.add_argument(
        "--noise",
        default="typical",
        help="'typical' (ADXL325-like), 'none', or overrides KEY=VALUE[,KEY=VALUE] of the typical noise "
        f"({', '.join(f.name for f in dataclasses.fields(NoiseSpec))})",
    )
    parser.add_argument("--channel-unit", choices=("V", "count", "m/s2", "g"), default="V")
    parser.add_argument("--sample-rate-hz", type=decimal_arg, default=100.0)
    parser.add_argument("--dwell-s", type=decimal_arg, default=30.0, help="static-12: dwell per position (s)")
    parser.add_argument("--g-local-m-s2", type=decimal_arg, default=9.81535)
    parser.add_argument(
        "--age-days", type=decimal_arg, default=0.0, help="age the unit by this many days first"
    )
    parser.add_argument("--serial", default="SN-SIM-0001")
    parser.add_argument(
        "--sidecar-lever-arm-m",
        default="0,0,0",
        metavar="X,Y,Z",
        help="lever arm the sidecar claims (what the bench believes), default 0,0,0",
    )
    parser.add_argument("--overwrite", action="store_true")
    parser.add_argument("-o", "--output", required=True, help="output CSV path")


def _floats(text: str, what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip() != ""]
    except ValueError as exc:
        raise BadInput(f"{what}: expected comma-separated numbers, got {text!r}") from exc
    if not values or not all(math.isfinite(v) for v in values):
        raise BadInput(f"{what}: expected finite numbers, got {text!r}")
    return values


def parse_effect(spec: str) -> tuple[str, dict[str, Any]]:
    """``ID:PARAM=V1,V2,...`` -> (id, {param: value shaped as the catalogue says})."""
    effect, sep, rest = spec.partition(":")
    if not sep or "=" not in rest:
        raise BadInput(f"--effect {spec!r}: expected ID:PARAM=V1,V2,...")
    if effect not in EFFECT_PARAMETERS:
        raise BadInput(f"--effect {spec!r}: unknown effect {effect!r}; known: {', '.join(EFFECT_PARAMETERS)}")
    params: dict[str, Any] = {}
    for item in rest.split(";"):
        name, _, values = item.partition("=")
        shape = EFFECT_PARAMETERS[effect].get(name)
        if shape is None:
            known = ", ".join(EFFECT_PARAMETERS[effect])
            raise BadInput(f"--effect {spec!r}: {effect} has no parameter {name!r}; it takes {known}")
        v = np.array(_floats(values, f"--effect {effect}:{name}"))
        size = int(np.prod([s for s in shape if s > 0])) if shape else 1
        if shape == ():
            if v.size != 1:
                raise BadInput(f"--effect {effect}:{name}: expected one value, got {v.size}")
            params[name] = float(v[0])
        elif -1 in shape:
            if v.size % size:
                raise BadInput(
                    f"--effect {effect}:{name}: expected a multiple of {size} values, got {v.size}"
                )
            params[name] = v.reshape(shape).tolist()
        else:
            if v.size != size:
                raise BadInput(f"--effect {effect}:{name}: expected {size} values, got {v.size}")
            params[name] = v.reshape(shape).tolist()
    return effect, params


def parse_noise(text: str, typical: NoiseSpec) -> NoiseSpec:
    """'typical', 'none' or KEY=VALUE overrides of ``typical``."""
    if text == "typical":
        return typical
    if text == "none":
        return NoiseSpec.silent()
    known = {f.name for f in dataclasses.fields(NoiseSpec)}
    overrides: dict[str, float] = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        if not sep or key not in known:
            raise BadInput(
                f"--noise {text!r}: expected typical, none or KEY=VALUE with KEY in {sorted(known)}"
            )
        overrides[key] = _floats(value, f"--noise {key}")[0]
    try:
        return dataclasses.replace(typical, **overrides)
    except ValueError as exc:
        raise BadInput(f"--noise {text!r}: {exc}") from exc


def simulate(args: argparse.Namespace) -> SimulatedRun:
    """Build the unit and the physics from ``args`` and run the chosen procedure."""
    effects = dict(parse_effect(s) for s in args.effect)
    unit_seed = args.seed if args.unit_seed is None else args.unit_seed
    if args.sample_rate_hz <= 0 or not math.isfinite(args.sample_rate_hz):
        raise BadInput(f"--sample-rate-hz must be > 0, got {args.sample_rate_hz}")
    base = SensorTruth.typical(args.channel_unit, seed=unit_seed)
    try:
        truth = base.aged(args.age_days, seed=unit_seed).with_effects(effects)
        truth = truth.with_noise(parse_noise(args.noise, base.noise))
        physics = SensorPhysics(
            truth,
            DEFAULT_AXES,
            None,
            args.g_local_m_s2,
            seed=args.seed,
            sample_rate_hz=args.sample_rate_hz,
            encoder_resolution_deg=1e-4,
        )
        if args.procedure == "static-12":
            return simulate_static(static12_poses_deg(), args.dwell_s, physics, args.sample_rate_hz)
        if args.procedure == "rate-1axis":
            return simulate_rate_steps(physics, args.sample_rate_hz)
        return simulate_oscillation(physics, args.sample_rate_hz)
    except ValueError as exc:
        raise BadInput(str(exc)) from exc


def run(args: argparse.Namespace) -> int:
    """Simulate and write the recording; prints the paths written."""
    lever = _floats(args.sidecar_lever_arm_m, "--sidecar-lever-arm-m")
    if len(lever) != 3:
        raise BadInput(f"--sidecar-lever-arm-m: expected 3 values, got {len(lever)}")
    sim = simulate(args)
    geometry = nominal_geometry(sim, (lever[0], lever[1], lever[2]))
    try:
        write_simulated(
            args.output, sim, serial=args.serial, geometry=geometry, seed=args.seed, overwrite=args.overwrite
        )
    except FileExistsError as exc:
        raise BadInput(f"{args.output}: exists (use --overwrite)") from exc
    print(f"wrote {args.output} ({sim.t_s.size} samples, {len(sim.segments)} windows, {sim.procedure})")
    return 0
