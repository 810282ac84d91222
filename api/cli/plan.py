"""``calbench plan --white UG [--wander UG --wander-tau S] [--random-walk UG] --scale PPM ... [--json]``.

Designs the procedure (``planned-static``, fitted by the static window fit, or
``planned-tumble``, the same tumble fitted by the every-sample fit; ``--fit``) that reaches the
target expanded uncertainties (k = 2) in the least table time on the table's limits (the bench
file's ``[table.limits]``: ``--bench-file`` or ``CALBENCH_BENCH_FILE``, else the simulated bench's),
for the unit's noise (µg/√Hz white, µg Gauss-Markov wander with its correlation time, µg/√s
random walk), and states its predicted U per group, the total table time (moves and settling
included) and the white-noise bound of any motion for that time (docs/planning.md).
``--compare PROC`` also predicts a registered static procedure with ``--dwell`` for the same unit.
Human output: the design, U and time; ``--json``: one object. Bad input: exit 2, one line.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from api.cli import BadInput, decimal_arg
from api.cli.run import add_bench_file_argument, settings_for
from bench.planning.evaluation import Evaluation, Targets, evaluate
from bench.planning.noise import G0_M_S2, UnitNoise, from_allan_terms
from bench.planning.report import evaluation_dict, plan_dict
from bench.planning.search import describe_sigmas, plan
from bench.procedures import build_procedure
from station.execution.devices import table_limits


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench plan``."""
    parser.add_argument(
        "--white", type=decimal_arg, default=None, metavar="UG_RT_HZ", help="white noise (µg/√Hz)"
    )
    parser.add_argument(
        "--noise-from",
        type=Path,
        default=None,
        metavar="REC.csv",
        help="take the noise from the Allan terms of a static stretch of this recording (m/s² or g channels; "
        "the largest term over the channels), instead of --white/--wander/--random-walk",
    )
    parser.add_argument(
        "--window-s",
        type=decimal_arg,
        nargs=2,
        default=None,
        metavar=("START", "END"),
        help="that stretch (s)",
    )
    parser.add_argument("--wander", type=decimal_arg, default=0.0, metavar="UG", help="bias wander σ (µg)")
    parser.add_argument(
        "--wander-tau", type=decimal_arg, default=100.0, metavar="S", help="its correlation time (s)"
    )
    parser.add_argument(
        "--random-walk", type=decimal_arg, default=0.0, metavar="UG_RT_S", help="bias random walk"
    )
    parser.add_argument(
        "--bias", type=decimal_arg, default=None, metavar="UG", help="target bias U, k=2 (µg)"
    )
    parser.add_argument(
        "--scale", type=decimal_arg, default=None, metavar="PPM", help="target scale U, k=2 (ppm)"
    )
    parser.add_argument(
        "--misalignment",
        type=decimal_arg,
        default=None,
        metavar="URAD",
        help="target misalignment U, k=2 (µrad)",
    )
    parser.add_argument(
        "--settle-s",
        type=decimal_arg,
        default=None,
        help="settling after each move (s; default the bench file's table.limits.settle_s, else 2)",
    )
    parser.add_argument(
        "--no-tilt", action="store_true", help="do not carry the base tilt as a nuisance parameter"
    )
    parser.add_argument(
        "--fit",
        choices=("best", "window", "every-sample"),
        default="best",
        help="design family: planned-static (window fit), planned-tumble (every-sample fit), or the "
        "shorter of the two (default)",
    )
    parser.add_argument("--max-minutes", type=decimal_arg, default=120.0, help="longest design tried (min)")
    parser.add_argument(
        "--compare", default=None, metavar="PROC", help="also predict this procedure (static)"
    )
    parser.add_argument("--dwell", type=decimal_arg, default=None, help="dwell of --compare (s)")
    parser.add_argument("--json", action="store_true", help="print the machine-readable result")
    add_bench_file_argument(parser)


def _line(e: Evaluation) -> str:
    return (
        f"{e.procedure.name} ({e.fit} fit) {json.dumps(e.procedure.parameters)}: "
        f"{e.duration_s / 60:.1f} min, "
        f"{describe_sigmas(e.predicted)}; K sigma {1e6 * e.predicted.k_rms:.3g} ppm rms = "
        f"{e.k_fraction_of_bound:.2f} x the bound of any motion ({1e6 * e.bound_k:.3g} ppm)"
    )


def noise_from_recording(path: Path, window_s: list[float] | None) -> UnitNoise:
    """The unit's noise from a recording's static stretch (selected as ``calbench allan`` does):
    the IEEE 952 terms of each channel, the largest of each term over the channels, the floor's τ
    where the worst channel's fitted curve is lowest (:func:`~bench.planning.noise.from_allan_terms`);
    a Gauss–Markov term the fit admitted, where its level exceeds that floor's wander, is the
    wander itself with its T_c.

    :raises BadInput: no such file, a channel unit other than m/s² or g, too short a stretch.
    """
    from bench.calibration.noise_stretch import noise_channels, select_noise_stretch
    from bench.estimation.allan import overlapping_allan
    from bench.estimation.noise_terms import fit_noise_model
    from bench.recording import read_recording

    if not path.is_file():
        raise BadInput(f"{path}: no such recording file")
    rec = read_recording(path)
    channels = noise_channels(rec)
    if channels.unit != "m/s2":
        raise BadInput(f"{path}: channel unit {channels.unit!r}; --noise-from needs a recording in m/s2 or g")
    stretch = select_noise_stretch(rec, window_s)
    r = overlapping_allan(channels.data[stretch.samples], rec.sidecar.sample_rate_hz)
    if r.taus_s.size < 6:
        raise BadInput(f"{path}: the stretch gives {r.taus_s.size} tau values; the noise fit needs 6")
    fits = fit_noise_model(r)
    worst = max(fits, key=lambda f: f.bias_instability_b)
    taus = np.geomspace(float(r.taus_s[0]), float(r.taus_s[-1]), 200)
    floor_tau = float(taus[int(np.argmin(worst.model_adev(taus)))])
    noise = from_allan_terms(
        max(f.white_n for f in fits),
        max(f.bias_instability_b for f in fits),
        max(f.rate_random_walk_k for f in fits),
        floor_tau,
    )
    # a Gauss–Markov term the fit admitted is the planner's wander itself (level and T_c)
    gm = max(fits, key=lambda f: f.gauss_markov_level if f.gauss_markov_level > 0 else -1.0)
    if gm.gauss_markov_level > noise.wander_m_s2 and math.isfinite(gm.gauss_markov_tc_s):
        noise = replace(noise, wander_m_s2=gm.gauss_markov_level, wander_tau_s=gm.gauss_markov_tc_s)
    return noise


def run(args: argparse.Namespace) -> int:
    """Plan, print, exit 0 (a plan found) or 1 (the targets are out of reach)."""
    try:
        if args.noise_from is not None:
            noise = noise_from_recording(args.noise_from, args.window_s)
        elif args.white is None:
            raise ValueError("give the noise: --white (µg/√Hz) or --noise-from REC.csv")
        else:
            noise = UnitNoise.from_ug(args.white, args.wander, args.wander_tau, args.random_walk)
        targets = Targets(
            None if args.bias is None else args.bias * 1e-6 * G0_M_S2,
            None if args.scale is None else args.scale * 1e-6,
            None if args.misalignment is None else args.misalignment * 1e-6,
        )
        if args.max_minutes <= 0:
            raise ValueError(f"--max-minutes must be > 0, got {args.max_minutes}")
        limits = table_limits(settings_for(args))
        compare = None
        if args.compare is not None:
            compare = evaluate(
                build_procedure(args.compare, dwell_s=args.dwell),
                noise,
                limits=limits,
                with_tilt=not args.no_tilt,
            )
        result = plan(
            noise,
            targets,
            limits=limits,
            settle_s=args.settle_s,
            with_tilt=not args.no_tilt,
            max_duration_s=args.max_minutes * 60,
            fits=("window", "every-sample") if args.fit == "best" else (args.fit,),
        )
    except ValueError as exc:
        raise BadInput(f"calbench plan: {exc}") from None
    if args.json:
        out: dict[str, Any] = plan_dict(result, noise.describe())
        out["compare"] = None if compare is None else evaluation_dict(compare)
        print(json.dumps(out, indent=2))
    else:
        print(f"noise: {noise.describe()}")
        if result.best is not None:
            print("plan: " + _line(result.best))
            for note in result.best.notes:
                print(f"note: {note}")
        for p in result.problems:
            print(f"no plan: {p}")
        if compare is not None:
            print("compare: " + _line(compare))
            for note in compare.notes:
                print(f"note: {note}")
    return 0 if result.best is not None else 1
