"""Two rates the slow tests sample with a few seeds, measured over many (docs/diagnose.md,
"Rates the tests sample").

``python -m benchmarks.study_sampled_rates pose N [FIRST_SEED]``: ``pose_error`` concealed at
3x its limit in N static-12 recordings (``tests.support.diagnose_cases.CASES["pose_error"]``,
seeds FIRST_SEED…, default 200): how many found it, and the largest |z| where found
(``test_effect_at_three_times_its_limit_is_found_mostly``).

``python -m benchmarks.study_sampled_rates cube N [FIRST_SEED]``: f_x³ on ax
(``benchmarks.library_cases.CASES["cubic"]``) in N static-12 recordings (seeds FIRST_SEED…,
default 200): how many claimed a catalogue effect (and which), how many claimed anything in the
catalogue other than ``cross_coupling``, and how many without a catalogue claim left the cube
unnamed (no term on ax that is f_x^3 or lists it) (``test_concealed_cube_is_not_taken_for_cross_coupling``).

Each prints one line per recording, then the counts and the share with its 95 % Clopper–Pearson
interval.
"""

from __future__ import annotations

import math
import sys

from scipy.stats import beta

from bench.calibration.diagnose import diagnose_recording


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The two-sided Clopper–Pearson interval of a binomial share k/n (Clopper & Pearson 1934)."""
    a = (1.0 - level) / 2.0
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1.0 - a, k + 1, n - k))
    return lo, hi


def share(label: str, k: int, n: int) -> str:
    """``label: k of n (p %, 95 % CI lo–hi %)``."""
    lo, hi = clopper_pearson(k, n)
    return f"{label}: {k} of {n} ({100 * k / n:.0f} %, 95 % CI {100 * lo:.0f}–{100 * hi:.0f} %)"


def pose(n: int, first: int) -> None:
    """pose_error at 3x its limit (module docstring)."""
    from tests.support.diagnose_cases import CASES, run_case

    case = CASES["pose_error"]
    found, zmax = 0, 0.0
    for seed in range(first, first + n):
        s = run_case(case, 3 * case.limit, seed=seed)
        found += s.found
        if s.found and not math.isnan(s.z):
            zmax = max(zmax, abs(s.z))
        print(f"pose_error 3x seed {seed}: found {s.found}, z {s.z:.2f}, others {list(s.others)}", flush=True)
    print(
        share(f"pose_error at 3x, seeds {first}-{first + n - 1}, found", found, n) + f"; max |z| {zmax:.2f}"
    )


def cube(n: int, first: int) -> None:
    """f_x³ on ax (module docstring)."""
    from benchmarks.library_cases import CASES, score

    case = CASES["cubic"]
    claimed = other = unnamed = 0
    for seed in range(first, first + n):
        d = diagnose_recording(case.recording(seed))
        s = score(case, d)
        named = any(x.channel == "ax" and "f_x^3" in (x.term, *x.confounded_with) for x in d.discovered)
        claimed += bool(s.catalogue)
        other += bool(s.catalogue) and s.catalogue != ("cross_coupling",)
        unnamed += not s.catalogue and not named
        print(
            f"cube seed {seed}: catalogue {list(s.catalogue)}, terms {list(s.terms)}, named {named}",
            flush=True,
        )
    span = f"seeds {first}-{first + n - 1}"
    print(share(f"cube, {span}, a catalogue claim", claimed, n))
    print(share(f"cube, {span}, a claim other than cross_coupling alone", other, n))
    print(share(f"cube, {span}, no claim and the cube not named", unnamed, n))


if __name__ == "__main__":
    which, count = sys.argv[1], int(sys.argv[2])
    start = int(sys.argv[3]) if len(sys.argv) > 3 else 200
    {"pose": pose, "cube": cube}[which](count, start)
