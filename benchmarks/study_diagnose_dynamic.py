"""Detection table of ``calbench diagnose`` on simulated moving-table recordings (docs/diagnose.md).

``python -m benchmarks.study_diagnose_dynamic [N] [effect ...]``: for each case of
``tests.support.diagnose_dynamic_cases.DYNAMIC_CASES``, N recordings (seeds 100…) with the
effect at 3x and at 10x its limit; prints, as a markdown table, the share found, the
largest parameter error in sigmas (median / max over the recordings where it was found),
the median sigma of the checked element and the other findings; then N clean recordings
of each kind (seeds 1000…) and their findings.
"""

from __future__ import annotations

import sys
import time
from collections import Counter

import numpy as np

from bench.calibration.diagnose import diagnose_recording
from tests.support.diagnose_dynamic_cases import DYNAMIC_CASES, DynamicCase, dynamic_z, moving_recording


def _sigma(case: DynamicCase, d: object, size: float) -> float:
    f = next((f for f in d.findings if f.effect == case.finding), None)  # type: ignore[attr-defined]
    if f is None:
        return float("nan")
    s = np.ravel(np.asarray(f.sigma[case.parameter], dtype=float))
    k = int(np.argmax(np.abs(np.asarray(case.truth))))
    return float(s[k])


def study(case: DynamicCase, n: int) -> str:
    """One table row for ``case``."""
    cells = []
    sigmas = []
    others: Counter[str] = Counter()
    for mult in (3, 10):
        size = mult * case.limit
        zs = []
        for seed in range(100, 100 + n):
            d = diagnose_recording(case.recording(size, seed))
            z = dynamic_z(case, d, size)
            others.update(f.effect for f in d.findings if f.effect not in (case.finding, "lever_arm"))
            if z is not None:
                zs.append(z)
                sigmas.append(_sigma(case, d, size))
        zt = f"{np.median(zs):.1f} / {np.max(zs):.1f}" if zs else "–"
        cells += [f"{len(zs)}/{n}", zt]
    other = ", ".join(f"{k} {v}" for k, v in sorted(others.items())) or "none"
    return (
        f"| {case.effect} ({case.kind}) | {case.limit:.2g} {case.unit} | {' | '.join(cells)} | "
        f"{np.nanmedian(sigmas):.2g} | {other} |"
    )


def main(argv: list[str] | None = None) -> None:
    """Print the moving-recording detection table (module docstring)."""
    args = sys.argv[1:] if argv is None else argv
    n = int(args[0]) if args and args[0].isdigit() else 6
    names = [a for a in args if not a.isdigit()] or list(DYNAMIC_CASES)
    print(
        "| effect (recording) | limit | found at 3x | max abs z at 3x (median / max) | found at 10x | "
        "max abs z at 10x (median / max) | sigma (largest element) | other findings |"
    )
    print("|---|---|---|---|---|---|---|---|")
    t0 = time.perf_counter()
    for name in names:
        print(study(DYNAMIC_CASES[name], n), flush=True)
    for kind in ("oscillation", "rate", "rate_tilted"):
        false = {}
        for seed in range(1000, 1000 + n):
            found = [f.effect for f in diagnose_recording(moving_recording({}, seed, kind=kind)).findings]
            if found:
                false[seed] = found
        print(f"clean {kind}: {len(false)} of {n} with a finding {false}", flush=True)
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
