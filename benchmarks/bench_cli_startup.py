"""Start-up time of the ``calbench`` command against ``python -c "import numpy"``, in one run.

Each command is started ``REPEATS`` times in a fresh interpreter and the best wall time is
kept (the least disturbed by the rest of the machine). "Of its own" is the command's time
minus the bare interpreter's (``python -c pass``), compared with numpy's import measured the
same way. The commands run with ``--help`` so that only start-up is timed: the parser, the
subcommand's module, nothing else.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

REPEATS = 7
CLI = [sys.executable, "-m", "api"]
CASES: dict[str, list[str]] = {
    "python -c pass": [sys.executable, "-c", "pass"],
    'python -c "import numpy"': [sys.executable, "-c", "import numpy"],
    "calbench --help": [*CLI, "--help"],
    "calbench calibrate --help": [*CLI, "calibrate", "--help"],
    "calbench diagnose --help": [*CLI, "diagnose", "--help"],
}


def best_wall_s(cmd: list[str], repeats: int = REPEATS) -> float:
    """Best of ``repeats`` wall times (s) of ``cmd`` run to completion, output discarded."""
    root = Path(__file__).resolve().parents[1]
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run(cmd, cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    """Print each command's best wall time, its own time, and the ratio to numpy's import."""
    times = {name: best_wall_s(cmd) for name, cmd in CASES.items()}
    bare = times["python -c pass"]
    numpy_own = times['python -c "import numpy"'] - bare
    print(f"{'command':32s} {'wall s':>8s} {'own s':>8s} {'own / numpy import':>20s}")
    for name, wall in times.items():
        own = wall - bare
        print(f"{name:32s} {wall:8.3f} {own:8.3f} {own / numpy_own:20.2f}")


if __name__ == "__main__":
    main()
