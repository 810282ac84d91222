"""Bench physics nobody listed: is each family named, and is nothing else claimed for it?

``python -m benchmarks.study_diagnose_families [N] [M] [FILTER] [CLEAN_FILTER]``: every case of
``tests/support/families_cases.py`` (filtered by a substring of its name) on N seeds (100…),
then M clean recordings of each kind (static, rate, oscillation, and a navigation-grade static
tumble on encoders that read in 1e-4° steps, declared in the sidecar; seeds 1000…). One markdown
row per case: named (the truth within 3 sigma, or ``unexplained`` on its channel), median and
largest |z| where named, recordings with a catalogue finding or discovered term the truth
does not hold (and which), seconds per recording. Clean rows: recordings with any finding,
discovered term or ``unexplained`` (the bench families' own findings counted apart).
"""

from __future__ import annotations

import sys
import time
from collections import Counter

import numpy as np

from bench.calibration.diagnose import diagnose_recording
from bench.recording import Recording
from tests.support.diagnose_cases import static_recording
from tests.support.diagnose_dynamic_cases import moving_recording
from tests.support.families_cases import CATALOGUE_IDS, cases, navigation_static_recording

CLEAN_KINDS = ("static", "rate", "oscillation", "static navigation-grade, 1e-4° encoder steps")


def clean_recording(kind: str, seed: int) -> Recording:
    """A recording of ``kind`` (``CLEAN_KINDS``) with nothing concealed."""
    if kind.startswith("static navigation"):
        return navigation_static_recording(seed)
    return static_recording({}, seed) if kind == "static" else moving_recording({}, seed, kind)


def main(n: int = 3, m: int = 3, only: str = "", clean_only: str = "") -> None:
    print("| case | kind | named | abs z (median / max) | other claim | claims | s per recording |")
    print("|---|---|---|---|---|---|---|")
    tot_named = tot_claim = tot = 0
    for case in cases():
        if n <= 0 or (only and only not in case.name):
            continue
        named = claimed = 0
        zs: list[float] = []
        what: Counter[str] = Counter()
        t0 = time.process_time()
        for seed in range(100, 100 + n):
            d = diagnose_recording(case.recording(seed))
            ok, z = case.score(d, case.truth(seed), case.size)
            extra = case.claimed(d)
            named += ok and not extra
            claimed += bool(extra)
            what.update(extra)
            if ok and np.isfinite(z):
                zs.append(z)
        tot_named += named
        tot_claim += claimed
        tot += n
        zt = f"{np.median(zs):.1f} / {max(zs):.1f}" if zs else "–"
        cl = ", ".join(f"{k} {v}" for k, v in what.most_common(4)) or "–"
        print(
            f"| {case.name} | {case.kind} | {named}/{n} | {zt} | {claimed}/{n} | {cl} | "
            f"{(time.process_time() - t0) / n:.1f} |",
            flush=True,
        )
    if tot:
        print(f"\nall cases: named with no other claim {tot_named}/{tot}, another claim {tot_claim}/{tot}")
    if m <= 0:
        return
    print("\n| clean | recordings | catalogue finding or discovered | bench-family finding | unexplained |")
    print("|---|---|---|---|---|")
    for kind in CLEAN_KINDS:
        if clean_only and clean_only not in kind:
            continue
        cat = fam = une = 0
        what = Counter[str]()
        for seed in range(1000, 1000 + m):
            d = diagnose_recording(clean_recording(kind, seed))
            c = [f.effect for f in d.findings if f.effect in CATALOGUE_IDS] + [x.term for x in d.discovered]
            b = [f.effect for f in d.findings if f.effect not in CATALOGUE_IDS]
            cat += bool(c)
            fam += bool(b)
            une += d.unexplained is not None
            what.update(c + b)
        cl = ", ".join(f"{k} {v}" for k, v in what.most_common(4))
        print(f"| {kind} | {m} | {cat} | {fam} | {une} | {cl}", flush=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    main(
        int(args[0]) if args else 3,
        int(args[1]) if len(args) > 1 else 3,
        args[2] if len(args) > 2 else "",
        args[3] if len(args) > 3 else "",
    )
