"""Detection table of ``calbench diagnose`` on simulated static-12 recordings (docs/diagnose.md).

``python -m benchmarks.study_diagnose_detection [N] [effect ...]``: for each effect of
``tests.support.diagnose_cases.CASES``, N recordings (seeds 100…) with the effect at 3x and at
10x its limit; prints, as a markdown table, the share found, the parameter error in
sigmas (median |z| and max |z| over the recordings where it was found), the median
sigma of the estimate and the limit it implies, sqrt(gate)·sigma, with the gate of the
first selection step (q·F(1 − α/N_c; q, n − p), α = 0.01, N_c candidates tried). Also
prints N clean recordings' false findings.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
from scipy.stats import f as f_dist

from bench.calibration.diagnose import diagnose_recording
from tests.support.diagnose_cases import CASES, Case, score, static_recording

N_CANDIDATES = 21
"""Candidates tried in the first step on static-12 (3 channels x 5 sensor effects, tilt,
3 encoder axes, pose)."""
N_PARAMS = 13


def gate_sigmas(q: int = 1, n: int = 36) -> float:
    """sqrt of the first step's likelihood-ratio gate: the detection limit in sigmas of the estimate."""
    return math.sqrt(q * float(f_dist.ppf(1.0 - 0.01 / N_CANDIDATES, q, n - N_PARAMS)))


def _sigma(case: Case, d_seed: int, size: float) -> float:
    d = diagnose_recording(case.recording(size, d_seed))
    f = {x.effect: x for x in d.findings}.get(case.effect)
    if f is None or case.parameter not in f.sigma:
        return float("nan")
    s = np.asarray(f.sigma[case.parameter], dtype=float)
    return float(s[case.index]) if case.index else float(np.sqrt(np.mean(s**2)))


def study(case: Case, n: int) -> str:
    """One table row for ``case``."""
    cells = []
    for mult in (3, 10):
        size = mult * case.limit
        scores = [
            score(case, diagnose_recording(case.recording(size, s)), case.build(size, s))
            for s in range(100, 100 + n)
        ]
        z = np.array([abs(s.z) for s in scores if s.found])
        found = sum(s.found for s in scores)
        zt = f"{np.median(z):.1f} / {np.max(z):.1f}" if z.size else "–"
        cells += [f"{found}/{n}", zt]
    sig = _sigma(case, 100, 10 * case.limit)
    implied = gate_sigmas() * sig if case.effect != "settling" else float("nan")
    return (
        f"| {case.effect} | {case.limit:.2g} {case.unit} | {' | '.join(cells)} | {sig:.2g} | {implied:.2g} |"
    )


def main(argv: list[str] | None = None) -> None:
    """Print the detection table (module docstring)."""
    args = sys.argv[1:] if argv is None else argv
    n = int(args[0]) if args and args[0].isdigit() else 10
    names = [a for a in args if not a.isdigit()] or list(CASES)
    print(f"gate: {gate_sigmas():.2f} sigma (q = 1, n = 36)")
    print(
        "| effect | limit | found at 3x | abs z at 3x (median / max) | found at 10x | abs z at 10x "
        "(median / max) | sigma of estimate | sqrt(gate)·sigma |"
    )
    print("|---|---|---|---|---|---|---|---|")
    t0 = time.perf_counter()
    for name in names:
        print(study(CASES[name], n), flush=True)
    false = [s for s in range(1000, 1000 + 4 * n) if diagnose_recording(static_recording({}, s)).findings]
    print(f"clean: {len(false)} of {4 * n} recordings with a finding {false}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
