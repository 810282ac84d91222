"""The static budget against Monte Carlo runs, with the Type B inputs' share of the fit's
between-window excess left in its Type A line (before) and taken out (after,
``bench.uncertainty.type_a``).

Runs simulated at sample level (``tests/support/budget_mc.py``: 12-position tumble, 10 s windows,
white + fast and slow Gauss-Markov noise), every Type B input drawn from its distribution,
refitted (``fit_static``) and given the budget a certificate would state. Cases: ``zero`` (no
Type B input: the fit's Type A alone), ``absorbed`` (inputs mostly absorbed by b and K:
``U_MC``), ``unmodelled`` (a base tilt, angle offsets and temperature coefficients that leave
residuals comparable to the window noise: ``U_MC_UNMODELLED``).

Per parameter, pooled over the seeds: spread of the errors / RMS u_c before and after (1 when
the budget is honest; the sampling error of the spread is 1/√(2(n − 1)) of it), and the RMS
Type A line over the RMS σ of the same runs fitted without any Type B input (1 when each input
is counted once), before and after.

    python -m benchmarks.study_budget_type_b CASE SEEDS DRAWS
"""

from __future__ import annotations

import sys
import time

import numpy as np

from bench.estimation.static_design import PARAMETER_NAMES
from tests.support.budget_mc import CASES, U_MC, monte_carlo, sd_sampling_error

ALL_CASES = {"zero": dict.fromkeys(U_MC, 0.0), **CASES}


def main(argv: list[str]) -> None:
    case, seeds, draws = argv[0], int(argv[1]), int(argv[2])
    t0 = time.time()
    runs = [monte_carlo(ALL_CASES[case], 1000 + s, draws) for s in range(seeds)]
    n = seeds * draws
    # pool: mean of the per-seed variances (same truth distribution), mean of the u_c²
    spread = np.sqrt(np.mean([r.spread**2 for r in runs], axis=0))

    def pooled(attr: str) -> np.ndarray:
        return np.sqrt(np.mean([getattr(r, attr) ** 2 for r in runs], axis=0))

    before, after = spread / pooled("u_before"), spread / pooled("u_after")
    a_before, a_after = pooled("u_fit") / pooled("u_clean"), pooled("u_type_a") / pooled("u_clean")
    clipped = sum(r.clipped_runs for r in runs)
    print(
        f"case {case}: {seeds} seeds x {draws} runs = {n}, spread sampling error "
        f"{100 * sd_sampling_error(n):.1f} %, runs with a component clipped at zero {clipped}, "
        f"{time.time() - t0:.0f} s"
    )
    print("| parameter | spread/u_c before | after | Type A/clean σ before | after |")
    print("|---|---|---|---|---|")
    for j, name in enumerate(PARAMETER_NAMES):
        print(f"| {name} | {before[j]:.3f} | {after[j]:.3f} | {a_before[j]:.3f} | {a_after[j]:.3f} |")
    per_seed = [r.spread / r.u_after for r in runs]
    print(
        "per seed, after, min–max over the 12 parameters:",
        ", ".join(f"{p.min():.2f}–{p.max():.2f}" for p in per_seed),
    )


if __name__ == "__main__":
    main(sys.argv[1:])
