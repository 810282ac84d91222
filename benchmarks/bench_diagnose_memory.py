"""Peak memory and CPU of ``diagnose`` against the number of static windows.

``python -m benchmarks.bench_diagnose_memory [m ...]`` (default 192 768 3000): for each m, a
clean static session of m windows (``bench_window_count.static_session``: the 12-pose tumble
repeated, 10 s dwells, 20 Hz, white noise and a Gauss-Markov bias wander) is simulated and
pickled by one child process, then loaded and diagnosed (``diagnose_recording``) by a fresh
one, which reports its own CPU time, wall time and peak RSS (``ru_maxrss``: the high-water mark
of that process alone, the loaded recording included). Printed: one row per m and the growth
exponent of the peak RSS above the smallest session's, against m (1: linear, 2: quadratic).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

DEFAULT_WINDOWS = (192, 768, 3000)

_SIMULATE = """
import pickle, sys
from benchmarks.bench_window_count import static_session
pickle.dump(static_session(int(sys.argv[1])), open(sys.argv[2], "wb"))
"""

_DIAGNOSE = """
import json, pickle, resource, sys, time
from bench.calibration.diagnose import diagnose_recording
rec = pickle.load(open(sys.argv[1], "rb"))
base = resource.getrusage(resource.RUSAGE_SELF)
t0 = time.perf_counter()
d = diagnose_recording(rec)
wall = time.perf_counter() - t0
ru = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({
    "cpu_s": ru.ru_utime + ru.ru_stime - base.ru_utime - base.ru_stime,
    "wall_s": wall,
    "peak_rss_mb": ru.ru_maxrss / 1024.0,
    "loaded_rss_mb": base.ru_maxrss / 1024.0,
    "findings": [f.effect for f in d.findings],
    "unexplained": d.unexplained is not None,
}))
"""


def _child(code: str, *args: str) -> str:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run(
        [sys.executable, "-c", code, *args], check=True, capture_output=True, text=True, env=env
    )
    return out.stdout


def measure(m: int, workdir: Path) -> dict[str, Any]:
    """One session of ``m`` windows: simulated in one child, diagnosed in another."""
    path = workdir / f"session_{m}.pkl"
    if not path.exists():
        _child(_SIMULATE, str(m), str(path))
    row: dict[str, Any] = json.loads(_child(_DIAGNOSE, str(path)).strip().splitlines()[-1])
    return row


def main(windows: tuple[int, ...]) -> None:
    """Print the table of the module docstring."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        print(f"{'windows':>7} {'cpu s':>7} {'wall s':>7} {'loaded MB':>9} {'peak MB':>8}", end="")
        print("  findings  unexplained")
        for m in windows:
            r = measure(m, Path(tmp))
            rows.append((m, r))
            cells = f"{m:7d} {r['cpu_s']:7.1f} {r['wall_s']:7.1f} {r['loaded_rss_mb']:9.0f}"
            cells += f" {r['peak_rss_mb']:8.0f}"
            print(f"{cells}  {len(r['findings']):8d}  {'yes' if r['unexplained'] else 'no'}", flush=True)
    if len(rows) >= 3:
        (m0, r0), rest = rows[0], rows[1:]
        x = [math.log(m / m0) for m, _ in rest]
        y = [math.log(max(float(r["peak_rss_mb"]) - float(r0["peak_rss_mb"]), 1e-3)) for _, r in rest]  # type: ignore[arg-type]
        a = (y[-1] - y[0]) / (x[-1] - x[0])
        print(
            f"growth of the peak RSS above {m0} windows, against m: exponent {a:.2f} (1 linear, 2 quadratic)"
        )


if __name__ == "__main__":
    args = tuple(int(a) for a in sys.argv[1:])
    main(args or DEFAULT_WINDOWS)
