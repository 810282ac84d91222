"""The static budget's Type A excess: the fit's σ as the Type A line (before: its Paule-Mandel
excess clipped at zero and inflated by ν/(ν − 2), Type B shares left in, k = 2) against the
certificate's Type A line (after: the unbiased MINQUE excess at the fit's weights with the Type B
shares out, ``bench.uncertainty.excess_moments``, and k = t_95.45 %(ν_eff) of its degrees of freedom).

Runs simulated at sample level (``tests/support/budget_mc.py``: 12-position tumble, 10 s windows,
white + fast and slow Gauss-Markov noise), refitted (``fit_static``), each with the budget a
certificate would state. Cases:

* ``none``: no Type B input, no pose error (the windows agree within their own noise but for
  the slow wander's small share);
* ``pose``: each pose placed 3 arc-minutes off (a real between-window excess, larger than the
  window noise across gravity), no Type B input;
* ``typeb``: the Type B inputs of ``U_MC_UNMODELLED`` drawn (a base tilt, angle offsets and
  temperature coefficients leaving residuals comparable to the window noise).

Per parameter: spread of the errors / RMS u_c, RMS z = error / u_c, and the coverage of U
(2 u_c before, k u_c after with k = t_95.45 %(ν_eff)). Margin (the acceptance of issue 21):
spread/u_c within 0.9–1.1 and z RMS within 0.8–1.25 on every parameter, coverage at least
95.45 % less three standard errors; a spread from n runs has a relative standard error of
1/√(2(n − 1)) (3.5 % at 400), which the printout states.

    python -m benchmarks.study_budget_excess CASE SEED RUNS
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from bench.estimation.static_design import PARAMETER_NAMES
from tests.support.budget_mc import POSE_ERROR_RAD, U_MC, U_MC_UNMODELLED, monte_carlo, sd_sampling_error

ZERO = dict.fromkeys(U_MC, 0.0)
CASES = {"none": (ZERO, 0.0), "pose": (ZERO, POSE_ERROR_RAD), "typeb": (U_MC_UNMODELLED, 0.0)}
SPREAD_MARGIN = (0.9, 1.1)
Z_MARGIN = (0.8, 1.25)
COVERAGE = 0.9545


def main(argv: list[str]) -> None:
    case, seed, runs = argv[0], int(argv[1]), int(argv[2])
    u_mc, pose = CASES[case]
    t0 = time.time()
    mc = monte_carlo(u_mc, seed, runs, paired=False, pose_error_rad=pose)
    before, after = mc.spread / mc.u_before, mc.spread / mc.u_after
    cover_floor = COVERAGE - 3 * math.sqrt(COVERAGE * (1 - COVERAGE) / runs)
    print(
        f"case {case}, seed {seed}: {runs} runs, "
        f"spread sampling error {100 * sd_sampling_error(runs):.1f} %, "
        f"runs with an excess component below zero {mc.clipped_runs}, {time.time() - t0:.0f} s"
    )
    print("| parameter | spread/u_c before | after | z RMS before | after | coverage before | after |")
    print("|---|---|---|---|---|---|---|")
    for j, name in enumerate(PARAMETER_NAMES):
        print(
            f"| {name} | {before[j]:.3f} | {after[j]:.3f} | {mc.z_before[j]:.3f} | {mc.z_after[j]:.3f} "
            f"| {mc.cover_before[j]:.3f} | {mc.cover_after[j]:.3f} |"
        )
    ok = (
        np.all((after > SPREAD_MARGIN[0]) & (after < SPREAD_MARGIN[1]))
        and np.all((mc.z_after > Z_MARGIN[0]) & (mc.z_after < Z_MARGIN[1]))
        and np.all(mc.cover_after >= cover_floor)
    )
    print(
        f"after: spread/u_c {after.min():.3f}–{after.max():.3f}, "
        f"z {mc.z_after.min():.3f}–{mc.z_after.max():.3f}, "
        f"coverage {mc.cover_after.min():.3f}–{mc.cover_after.max():.3f} (floor {cover_floor:.3f}); "
        f"before: spread/u_c {before.min():.3f}–{before.max():.3f}, z {mc.z_before.min():.3f}–"
        f"{mc.z_before.max():.3f}, coverage {mc.cover_before.min():.3f}–{mc.cover_before.max():.3f}; "
        f"margin {'met' if ok else 'NOT met'}"
    )


if __name__ == "__main__":
    main(sys.argv[1:])
