"""Cost and peak memory of reading, calibrating and diagnosing against the recording's length.

Two simulated 1 kHz recordings in calbench-recording/1 are written at each length L: a
``static-12`` run whose twelve dwells share L (dwell ≈ L / 12) and an ``oscillation-2axis``
run oscillating for L (a moving table: the dynamic fit). Each is then read, calibrated and
diagnosed as a user does it, one fresh process per command (``python -c read_recording``,
``calbench calibrate REC.csv --json``, ``calbench diagnose REC.csv --json``), and the child's
own resource usage is taken from ``os.wait4``: wall time, CPU time (user + system) and peak
resident set size (``ru_maxrss``, KiB on Linux).

Printed per command: n (samples), wall s, CPU s, peak RSS MB, the raw data size
n × columns × 8 bytes, and (peak − the interpreter's RSS after importing the same stack) /
raw size; then the growth exponents a of CPU ∝ n^a and b of (peak − base) ∝ n^b (least
squares in log-log over the lengths).

Run: ``python -m benchmarks recording_size`` (10 min, 1 h); a short check with
``python -m benchmarks.bench_recording_size --quick`` (2.5, 5, 10 min), or lengths in minutes
as arguments (``python -m benchmarks.bench_recording_size 10 60``). Options: ``--keep-mib X``
runs ``calibrate`` and ``diagnose`` with ``bench.estimation.motion_data.KEEP_BYTES`` lowered to
X MiB, so the regressors' keep-or-form-per-chunk threshold falls between two short lengths and
its cost is measured in minutes (``--keep-mib 100 2.5 5``: 2.5 min keeps its 65 MB of
regressors, 5 min forms them per chunk); ``--only KIND`` (``static`` or ``oscillation``) and
``--commands C,…`` restrict the sweep.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from api.simulated_recording import write_simulated
from drivers.sim.offline import (
    DEFAULT_AXES,
    SimulatedRun,
    simulate_oscillation,
    simulate_static,
    static12_poses_deg,
)
from drivers.sim.physics import SensorPhysics, SensorTruth

RATE_HZ = 1000.0
LENGTHS_MIN = (10.0, 60.0)
"""Default lengths (min); a 4 h moving recording needs about 10 GB (docs/benchmarks.md): ask for
it by argument (``python -m benchmarks.bench_recording_size 10 60 240``)."""
QUICK_LENGTHS_MIN = (2.5, 5.0, 10.0)
OSCILLATION_T1_S = 30.0
"""Long period of ``simulate_oscillation`` (2.5 × its default 12 s short period); the
oscillation lasts a whole number of them."""
COMMANDS = ("read", "calibrate", "diagnose")
BASE_SCRIPTS = {
    "read": "import bench.recording",
    "calibrate": "import numpy, scipy, bench.recording, bench.calibration, api.cli.calibrate",
    "diagnose": "import numpy, scipy, bench.recording, bench.calibration.diagnose, api.cli.diagnose",
}
"""What each command's process holds before it reads a sample: its peak RSS is the base that the
memory per sample is counted above."""
READ_SCRIPT = "import sys; from bench.recording import read_recording; read_recording(sys.argv[1])"
CLI_SCRIPT = (
    "import sys; import bench.estimation.motion_data as md; md.KEEP_BYTES = int(sys.argv[1]); "
    "from api.cli import main; sys.exit(main(sys.argv[2:]))"
)
"""``calbench`` with the regressors' keep threshold set to ``argv[1]`` bytes (``--keep-mib``)."""


@dataclass(frozen=True)
class ChildCost:
    """Resources one child process used: wall s, CPU s (user + system), peak RSS (bytes)."""

    wall_s: float
    cpu_s: float
    peak_rss_bytes: int
    stdout: str


MEASURE_SCRIPT = """
import json, os, subprocess, sys, time
t0 = time.perf_counter()
proc = subprocess.Popen(sys.argv[2:])
_, status, ru = os.wait4(proc.pid, 0)
wall = time.perf_counter() - t0
with open(sys.argv[1], "w") as f:
    json.dump([os.waitstatus_to_exitcode(status), wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss], f)
"""
"""Runs the command and writes [exit code, wall s, CPU s, ru_maxrss KiB] of it alone. It is a small
process of its own because Linux keeps the high-water RSS of the memory a child was spawned from
(``vfork``) across ``exec``: spawned from the benchmark, which holds the simulated run, every
child would report at least the benchmark's own peak."""


def run_child(argv: list[str]) -> ChildCost:
    """Run ``argv`` to completion under :data:`MEASURE_SCRIPT`: its own wall, CPU and peak RSS.

    :raises RuntimeError: the command exited non-zero (its stderr's last line is quoted).
    """
    with tempfile.TemporaryDirectory() as d:
        usage_path = Path(d) / "usage.json"
        proc = subprocess.run(
            [sys.executable, "-c", MEASURE_SCRIPT, str(usage_path), *argv],
            capture_output=True,
            text=True,
            check=False,
        )
        code, wall, cpu, maxrss_kib = (
            json.loads(usage_path.read_text()) if usage_path.exists() else (-1, 0, 0, 0)
        )
    if proc.returncode != 0 or code != 0:
        last = proc.stderr.strip().splitlines()[-1:] or ["(no stderr)"]
        raise RuntimeError(f"{' '.join(argv[:3])} … exited {code}: {last[0]}")
    return ChildCost(float(wall), float(cpu), int(maxrss_kib) * 1024, proc.stdout)


def simulate(kind: str, length_s: float, seed: int = 11) -> SimulatedRun:
    """A clean 1 kHz run of about ``length_s`` seconds: ``static`` (12 dwells) or ``oscillation``."""
    physics = SensorPhysics(
        SensorTruth.typical("V", seed=seed), DEFAULT_AXES, seed=seed, sample_rate_hz=RATE_HZ
    )
    if kind == "static":
        return simulate_static(static12_poses_deg(), length_s / 12.0, physics, RATE_HZ)
    duration = max(1, round(length_s / OSCILLATION_T1_S)) * OSCILLATION_T1_S
    return simulate_oscillation(physics, RATE_HZ, duration_s=duration)


def command_argv(command: str, csv_path: Path, keep_bytes: int | None = None) -> list[str]:
    """The child process of ``command`` on ``csv_path``, run as a user runs it (with
    ``keep_bytes``: as :data:`CLI_SCRIPT`, the regressors kept up to that many bytes)."""
    if command == "read":
        return [sys.executable, "-c", READ_SCRIPT, str(csv_path)]
    if keep_bytes is not None:
        return [sys.executable, "-c", CLI_SCRIPT, str(keep_bytes), command, str(csv_path), "--json"]
    cli = Path(sys.executable).with_name("calbench")
    return [str(cli), command, str(csv_path), "--json"]


def growth_exponent(n: list[float], y: list[float]) -> float:
    """a of y ∝ n^a, least squares on log y = a log n + c (NaN with fewer than two points)."""
    if len(n) < 2 or min(y) <= 0:
        return math.nan
    return float(np.polyfit(np.log(n), np.log(y), 1)[0])


def main(
    lengths_min: tuple[float, ...] = LENGTHS_MIN,
    *,
    keep_bytes: int | None = None,
    kinds: tuple[str, ...] = ("static", "oscillation"),
    commands: tuple[str, ...] = COMMANDS,
) -> None:
    """Print the sweep (module docstring); ``keep_bytes``: :data:`CLI_SCRIPT`'s threshold."""
    base = {c: run_child([sys.executable, "-c", script]).peak_rss_bytes for c, script in BASE_SCRIPTS.items()}
    print(
        f"load average {os.getloadavg()[0]:.1f}; {RATE_HZ:.0f} Hz; base (interpreter + imports) peak RSS MB: "
        + ", ".join(f"{c} {b / 1e6:.0f}" for c, b in base.items())
    )
    if keep_bytes is not None:
        print(f"regressors kept up to {keep_bytes / 2**20:.0f} MiB ({keep_bytes // 432} samples)")
    for kind in kinds:
        print(
            f"\n{kind}: {'length':>8} {'n':>10} {'command':>9} {'wall s':>8} {'cpu s':>8} "
            f"{'peak MB':>8} {'raw MB':>7} {'(peak-base)/raw':>15}"
        )
        ns: list[float] = []
        cpu: dict[str, list[float]] = {c: [] for c in commands}
        mem: dict[str, list[float]] = {c: [] for c in commands}
        for minutes in lengths_min:
            with tempfile.TemporaryDirectory() as d:
                path = Path(d) / f"{kind}.csv"
                run = simulate(kind, minutes * 60.0)
                rec = write_simulated(path, run, serial="SN-SIZE", write_truth=False)
                n = rec.t_s.size
                raw_bytes = n * (4 + DEFAULT_AXES.shape[0] + (rec.temp_c is not None)) * 8
                del run, rec
                ns.append(float(n))
                for command in commands:
                    cost = run_child(command_argv(command, path, keep_bytes))
                    if command != "read":
                        json.loads(cost.stdout)  # the answer is a whole JSON document
                    over = cost.peak_rss_bytes - base[command]
                    cpu[command].append(cost.cpu_s)
                    mem[command].append(float(max(over, 1)))
                    print(
                        f"{'':>8}{minutes:7.1f}m {n:10d} {command:>9} {cost.wall_s:8.2f} {cost.cpu_s:8.2f} "
                        f"{cost.peak_rss_bytes / 1e6:8.0f} {raw_bytes / 1e6:7.0f} {over / raw_bytes:15.2f}",
                        flush=True,
                    )
        for command in commands:
            a = growth_exponent(ns, cpu[command])
            b = growth_exponent(ns, mem[command])
            print(f"  {command:>9}: cpu ∝ n^{a:.2f}, peak - base ∝ n^{b:.2f}")


def _option(args: list[str], name: str) -> str | None:
    """Remove ``name VALUE`` from ``args`` and return VALUE (``None`` when absent)."""
    if name not in args:
        return None
    i = args.index(name)
    if i + 1 >= len(args):
        raise SystemExit(f"bench_recording_size: {name} needs a value")
    value = args[i + 1]
    del args[i : i + 2]
    return value


if __name__ == "__main__":
    args = sys.argv[1:]
    keep_mib = _option(args, "--keep-mib")
    only = _option(args, "--only")
    picked = _option(args, "--commands")
    quick = "--quick" in args
    args = [a for a in args if a != "--quick"]
    lengths = tuple(float(a) for a in args) if args else QUICK_LENGTHS_MIN if quick else LENGTHS_MIN
    main(
        lengths,
        keep_bytes=None if keep_mib is None else int(float(keep_mib) * 2**20),
        kinds=("static", "oscillation") if only is None else (only,),
        commands=COMMANDS if picked is None else tuple(picked.split(",")),
    )
