"""Device faults at random during whole runs of every procedure: the rate of runs that end
completed with no sample lost unseen.

Each run is a real ``calbench run PROCEDURE --sim`` process (the simulated bench in its own
process, 100 Hz at ×25, dwell 5 s), the procedures taken in turn. While it records, faults are
injected into its simulated bench from outside, one after another at random wall times
(uniform 2–8 s after the previous one ended, from its first complete window on),
``faults_per_run`` per run, each one of:

* **stall**: the simulator process frozen (SIGSTOP) for a uniform 1–30 s, then let go;
* **reset**: the simulator process killed (SIGKILL): every link drops, all state is lost;
* **lost line**: the table's connection cut (SIGUSR1 to the simulator), the controller
  running on.

A run *succeeds* when the command exits 0 with PASS, the database says ``completed``, the
recording has every window of the procedure, time increases, and every hole in its time
axis (a step over 1.5 sample periods) is matched by a recorded gap — no sample lost unseen.
Reported: faults by kind, automatic resumes, the success rate with a 95 % Wilson interval,
and the wall time.

Run: ``python -m benchmarks.study_device_faults [n_runs] [faults_per_run] [seed] [parallel]``
(default 12 runs × 5 faults = 60 faults, two runs at a time).
"""

from __future__ import annotations

import json
import math
import os
import random
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.recording.reader import read_recording
from tests.support.sim_faults import kill, lose_line, sim_pid, stall

PROCEDURES = ("static-12", "rate-1axis", "oscillation-2axis")
N_WINDOWS = {"static-12": 12, "rate-1axis": 42, "oscillation-2axis": 3}
SPEED, RATE_HZ, DWELL_S = 25.0, 100.0, 5.0
CALBENCH = str(Path(sys.executable).with_name("calbench"))


@dataclass
class Injector:
    """Injects ``n`` faults into the simulator of the run process ``owner``, one at a time."""

    owner: subprocess.Popen[str]
    n: int
    rng: random.Random
    db: Path
    done: list[tuple[str, float]] = field(default_factory=list)

    def recording(self) -> bool:
        """The run exists and records (a fault before it starts is a refused start, not studied)."""
        try:
            with sqlite3.connect(self.db) as conn:
                return conn.execute("SELECT count(*) FROM run_window").fetchone()[0] > 0
        except sqlite3.Error:
            return False

    def run(self) -> None:
        while not self.recording() and self.owner.poll() is None:
            time.sleep(0.2)
        while len(self.done) < self.n and self.owner.poll() is None:
            time.sleep(self.rng.uniform(2.0, 8.0))
            pid = sim_pid(self.owner.pid)
            if pid is None or self.owner.poll() is not None:
                continue  # between simulators (a resume is starting one): try later
            kind = self.rng.choice(("stall", "reset", "lost line"))
            if kind == "stall":
                seconds = self.rng.uniform(1.0, 30.0)
                stall(pid, seconds)
                self.done.append((kind, seconds))
            elif kind == "reset":
                kill(pid)
                self.done.append((kind, 0.0))
            else:
                lose_line(pid)
                self.done.append((kind, 0.0))


def check_recording(path: str, n_windows: int) -> str | None:
    """Why the recording is not whole (``None``: every window, every hole a recorded gap)."""
    rec = read_recording(path)
    segments = rec.sidecar.segments or ()
    if len(segments) != n_windows:
        return f"{len(segments)} windows of {n_windows}"
    step = np.diff(rec.t_s)
    if not np.all(step > 0):
        return "time does not increase"
    holes = int(np.sum(step > 1.5 / rec.sidecar.sample_rate_hz))
    gaps = rec.sidecar.extra.get("calbench_gaps", [])
    return None if holes <= len(gaps) else f"{holes} holes in t, {len(gaps)} recorded gaps"


def one_run(tmp: Path, i: int, faults: int, rng: random.Random) -> dict[str, object]:
    proc_name = PROCEDURES[i % len(PROCEDURES)]
    data = tmp / f"run{i}"
    env = {
        **os.environ,
        "CALBENCH_DATA_DIR": str(data),
        "CALBENCH_DATABASE_URL": f"sqlite:///{data / 'calbench.db'}",
        "CALBENCH_SIM_SAMPLE_RATE_HZ": str(RATE_HZ),
        "CALBENCH_BENCH_NAME": f"bench-faults-{i}",
    }
    cmd = [CALBENCH, "run", proc_name, "--unit", f"SN-FAULT-{i}", "--sim", "--sim-speed", str(SPEED)]
    cmd += ["--dwell-s", str(DWELL_S), "--seed", str(i), "--json"]
    t0 = time.monotonic()
    owner = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    injector = Injector(owner, faults, rng, data / "calbench.db")
    thread = threading.Thread(target=injector.run, daemon=True)
    thread.start()
    out, err = owner.communicate(timeout=3600)
    thread.join(timeout=60)
    why = None
    try:
        body = json.loads(out)
    except ValueError:
        body = {}
        why = f"exit {owner.returncode}: {err.strip().splitlines()[-1:]}"
    with sqlite3.connect(data / "calbench.db") as conn:
        row = conn.execute("SELECT state, resume_count FROM run").fetchone()
    state, resumes = row if row is not None else ("no run", 0)
    if why is None and (owner.returncode != 0 or body.get("outcome") != "PASS" or state != "completed"):
        why = f"exit {owner.returncode}, {body.get('outcome')}, {state}: {body.get('error')}"
    if why is None:
        why = check_recording(str(body["recording"]), N_WINDOWS[proc_name])
    return {
        "procedure": proc_name,
        "faults": injector.done,
        "resumes": int(resumes or 0),
        "ok": why is None,
        "why": why,
        "wall_s": time.monotonic() - t0,
    }


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a rate k/n."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    n_runs = int(args[0]) if args else 12
    per_run = int(args[1]) if len(args) > 1 else 5
    rng = random.Random(int(args[2]) if len(args) > 2 else 2026)
    parallel = int(args[3]) if len(args) > 3 else 2
    t0 = time.monotonic()
    results = []
    with tempfile.TemporaryDirectory(prefix="calbench-faults-") as tmp:
        # two runs at a time, each with its own generator (the same faults whatever the order)
        seeds = [rng.randrange(2**32) for _ in range(n_runs)]
        with ThreadPoolExecutor(max_workers=parallel) as pool:
            futures = [
                pool.submit(one_run, Path(tmp), i, per_run, random.Random(seeds[i])) for i in range(n_runs)
            ]
            for i, future in enumerate(futures):
                r = future.result()
                results.append(r)
                kinds = ", ".join(f"{k}{f' {s:.1f} s' if s else ''}" for k, s in r["faults"])  # type: ignore[attr-defined]
                print(
                    f"run {i:2d} {r['procedure']:18s} faults: {kinds or '-':50s} resumes {r['resumes']} "
                    f"{'ok' if r['ok'] else 'FAILED: ' + str(r['why'])} ({r['wall_s']:.0f} s)",
                    flush=True,
                )
    kinds = Counter(k for r in results for k, _ in r["faults"])  # type: ignore[attr-defined]
    n_faults = sum(kinds.values())
    ok = sum(bool(r["ok"]) for r in results)
    lo, hi = wilson(ok, len(results))
    stalls = [s for r in results for k, s in r["faults"] if k == "stall"]  # type: ignore[attr-defined]
    print(
        f"\n{len(results)} runs, {n_faults} faults ({kinds['stall']} stalls of "
        f"{min(stalls, default=0):.1f}-{max(stalls, default=0):.1f} s, {kinds['reset']} resets, "
        f"{kinds['lost line']} lost lines), {sum(int(r['resumes']) for r in results)} automatic resumes "  # type: ignore[call-overload]
        f"(by procedure: "
        + ", ".join(
            f"{p} {sum(len(r['faults']) for r in results if r['procedure'] == p)} faults"  # type: ignore[arg-type]
            for p in PROCEDURES
        )
        + f"); completed with no sample lost unseen: {ok}/{len(results)} = {ok / max(1, len(results)):.0%} "
        f"(95 % CI {lo:.0%}-{hi:.0%}); wall {time.monotonic() - t0:.0f} s"
    )
    return 0 if ok == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
