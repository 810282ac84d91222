"""The cost of a plan (``bench.planning.search.plan``) by fit and longest table time, optionally
against the planner of another git revision in the same process.

Cases: the ADXL325-like unit (``UnitNoise.from_ug(250, 40, 200)``), scale U 400 ppm (met by
one pass), 20 ppm (a bisection over repeats) and 1 ppm (met by no design), each within
``max_minutes`` of 3, 10, 20, 40, 60 and 120 min.

``--vs REV`` loads ``bench/planning/search.py`` and ``bench/planning/every_sample.py`` as they
are at git revision REV into modules of their own (the rest of ``bench`` is this checkout's) and
times the two planners in turn, case by case (A B A B …), so both see the machine's load of the
same moment; each row gives the median of ``--runs`` wall times and the median of the pairwise
ratios, and checks that both chose the same design with the same predicted σ (1e-9 relative).

Run: ``nice .venv/bin/python -m benchmarks.bench_plan [--fit every-sample] [--runs 3]
[--vs REV] [--minutes 3,20,60]``; docs/benchmarks.md quotes its output.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from bench.planning import search
from bench.planning.noise import UnitNoise

ROOT = Path(__file__).resolve().parent.parent
NOISE = UnitNoise.from_ug(250, 40, 200)
SCALES_PPM = (400.0, 20.0, 1.0)
MINUTES = (3.0, 10.0, 20.0, 40.0, 60.0, 120.0)


def planner_at(rev: str) -> ModuleType:
    """``bench.planning.search`` of git revision ``rev``, with that revision's every-sample module."""
    tmp = Path(tempfile.mkdtemp(prefix="plan-rev-"))
    mods: dict[str, ModuleType] = {}
    for name in ("every_sample", "search"):
        src = subprocess.run(
            ["git", "-C", str(ROOT), "show", f"{rev}:bench/planning/{name}.py"],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        src = src.replace("from bench.planning.every_sample import", "from rev_every_sample import")
        path = tmp / f"rev_{name}.py"
        path.write_text(src)
        spec = importlib.util.spec_from_file_location(f"rev_{name}", path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        sys.modules[f"rev_{name}"] = mod
        spec.loader.exec_module(mod)
        mods[name] = mod
    return mods["search"]


def run(planner: ModuleType, fit: str, scale_ppm: float, minutes: float) -> tuple[float, Any]:
    """Wall seconds of one plan and the plan."""
    targets = planner.Targets(scale=scale_ppm * 1e-6)
    t0 = time.perf_counter()
    p = planner.plan(NOISE, targets, max_duration_s=minutes * 60, fits=(fit,))
    return time.perf_counter() - t0, p


def same(a: Any, b: Any) -> bool:
    """Both plans chose the same design (or none) with the same predicted σ to 1e-9 relative."""
    for x, y in ((a.best, b.best), (a.closest, b.closest)):
        if (x is None) != (y is None):
            return False
        if x is None:
            continue
        if x.procedure.parameters != y.procedure.parameters or x.duration_s != y.duration_s:
            return False
        u = np.concatenate([x.predicted.bias_m_s2, x.predicted.k_elements.ravel()])
        v = np.concatenate([y.predicted.bias_m_s2, y.predicted.k_elements.ravel()])
        if np.max(np.abs(u - v) / np.abs(v)) > 1e-9:
            return False
    return a.problems == b.problems


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fit", default="every-sample", choices=("window", "every-sample"))
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--vs", default=None, help="git revision whose planner is timed in turn")
    ap.add_argument("--minutes", default=",".join(f"{m:g}" for m in MINUTES))
    args = ap.parse_args(argv)
    other = planner_at(args.vs) if args.vs else None
    minutes = [float(m) for m in args.minutes.split(",")]
    print(f"fit {args.fit}, median of {args.runs} runs" + (f", against {args.vs}" if other else ""))
    for scale in SCALES_PPM:
        for m in minutes:
            a_s, b_s, ratio = [], [], []
            ok = True
            for _ in range(args.runs):
                ta, pa = run(search, args.fit, scale, m)
                a_s.append(ta)
                if other is not None:
                    tb, pb = run(other, args.fit, scale, m)
                    b_s.append(tb)
                    ratio.append(ta / tb)
                    ok = ok and same(pa, pb)
            chosen = pa.best.procedure.parameters if pa.best is not None else "none meets"
            line = f"scale {scale:5g} ppm, {m:5g} min: {statistics.median(a_s):7.2f} s"
            if other is not None:
                line += (
                    f"  (was {statistics.median(b_s):7.2f} s, ratio {statistics.median(ratio):.2f}, "
                    f"{'same plan' if ok else 'PLANS DIFFER'})"
                )
            print(f"{line}  {chosen}", flush=True)


if __name__ == "__main__":
    main()
