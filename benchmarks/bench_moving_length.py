"""CPU time of ``calibrate`` on a moving-table recording against its length: linear in samples?

A clean ``oscillation-2axis`` run at 1 kHz (``bench_recording_size.simulate``) is written at each
length and calibrated as a user does it (``calbench calibrate REC.csv --json``, one fresh process
each); the child's CPU time (user + system, ``os.wait4``) and peak RSS are printed with the CPU
per sample and, for each length against the one before, the CPU ratio beside the samples' ratio.
Twice the samples should cost at most 2.3× the CPU (and no cliff where the regressors stop
fitting ``motion_data.KEEP_BYTES``: 41 min at 1 kHz for all six of them, 2 h for G and B).

Run: ``python -m benchmarks.bench_moving_length`` (5, 10, 20, 40 min) or with lengths in minutes
(``python -m benchmarks.bench_moving_length 30 60``); ``--keep-mib X`` lowers the keep budget in
the children so the threshold falls between short lengths (``--keep-mib 100 2.5 5``). CPU times
are the children's own; on a loaded machine the ratios, measured in one run, are what to quote.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

from api.simulated_recording import write_simulated
from benchmarks.bench_recording_size import _option, command_argv, run_child, simulate

LENGTHS_MIN = (5.0, 10.0, 20.0, 40.0)
MAX_DOUBLING_RATIO = 2.3
"""Target: CPU(2L) / CPU(L) at most this (linear in samples, with some fixed cost)."""


def main(lengths_min: tuple[float, ...] = LENGTHS_MIN, *, keep_bytes: int | None = None) -> None:
    """Print the sweep (module docstring)."""
    print(f"load average {os.getloadavg()[0]:.1f}; oscillation-2axis at 1 kHz; calbench calibrate --json")
    if keep_bytes is not None:
        print(f"regressors kept up to {keep_bytes / 2**20:.0f} MiB")
    head = (
        ("minutes", 8),
        ("samples", 9),
        ("cpu s", 8),
        ("peak MB", 8),
        ("cpu us/sample", 13),
        ("cpu ratio", 9),
    )
    print(" ".join(f"{h:>{w}}" for h, w in head), f"{'n ratio':>7}")
    prev: tuple[int, float] | None = None
    for minutes in lengths_min:
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "oscillation.csv"
            run = simulate("oscillation", minutes * 60.0)
            n = write_simulated(path, run, serial="SN-LENGTH", write_truth=False).t_s.size
            del run
            cost = run_child(command_argv("calibrate", path, keep_bytes))
        ratio = "" if prev is None else f"{cost.cpu_s / prev[1]:9.2f} {n / prev[0]:7.2f}"
        print(
            f"{minutes:8.1f} {n:9d} {cost.cpu_s:8.1f} {cost.peak_rss_bytes / 1e6:8.0f} "
            f"{1e6 * cost.cpu_s / n:13.2f} {ratio}",
            flush=True,
        )
        prev = (n, cost.cpu_s)
    print(f"target: cpu ratio <= {MAX_DOUBLING_RATIO} for twice the samples")


if __name__ == "__main__":
    args = sys.argv[1:]
    keep_mib = _option(args, "--keep-mib")
    main(
        tuple(float(a) for a in args) if args else LENGTHS_MIN,
        keep_bytes=None if keep_mib is None else int(float(keep_mib) * 2**20),
    )
