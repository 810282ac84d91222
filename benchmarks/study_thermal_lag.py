"""A temperature effect through a thermal lag on static-12 recordings: named, misattributed, or
false (``tests/support/thermal_lag_cases.py``; docs/diagnose.md, "Bench physics beyond the
catalogue").

``python -m benchmarks.study_thermal_lag [N] [M] [P]``: the lag cases (tc 3e-3, 1e-2, 3e-2
m/s²/°C on ay; τ 30, 60, 120 s) on N seeds (100…); plain ``temperature_bias`` (no lag; 1e-3,
3e-3, 1e-2 m/s²/°C) on P seeds (300…); M clean recordings on the same cycling temperature
(seeds 1000…). One markdown row per case: named (the lag within 3 sigma, or ``unexplained`` on
ay with no claim), median |z| of tc and τ where found, RMS z, other claims, seconds per
recording. Null rows: a ``thermal_lag`` finding (misattribution / false finding), any other
finding.
"""

from __future__ import annotations

import sys
import time
from collections import Counter

import numpy as np

from bench.calibration.diagnose import diagnose_recording
from tests.support.thermal_lag_cases import (
    lag_finding,
    lag_recording,
    named,
    other_claims,
    plain_named,
    z_scores,
)

LAG_TC = (3e-3, 1e-2, 3e-2)
LAG_TAU_S = (30.0, 60.0, 120.0)
PLAIN_TC = (1e-3, 3e-3, 1e-2)


def main(n: int = 4, m: int = 20, p: int = 10) -> None:
    if n > 0:
        print(
            "| tc (m/s²/°C) | τ (s) | named | found as thermal_lag | abs z tc / τ (median) | RMS z tc / τ "
            "| other claim | claims | s per recording |"
        )
        print("|---|---|---|---|---|---|---|---|---|")
    for tc in LAG_TC if n > 0 else ():
        for tau in LAG_TAU_S:
            ok = found = other = 0
            zc: list[float] = []
            zt: list[float] = []
            what: Counter[str] = Counter()
            t0 = time.process_time()
            for seed in range(100, 100 + n):
                d = diagnose_recording(lag_recording(tc, tau, seed))
                ok += named(d, tc)
                found += lag_finding(d) is not None
                extra = other_claims(d, "thermal_lag")
                other += bool(extra)
                what.update(extra)
                a, b = z_scores(d, tc, tau)
                if np.isfinite(a):
                    zc.append(a)
                    zt.append(b)
            med = f"{np.median(np.abs(zc)):.1f} / {np.median(np.abs(zt)):.1f}" if zc else "–"
            rms = (
                f"{np.sqrt(np.mean(np.square(zc))):.2f} / {np.sqrt(np.mean(np.square(zt))):.2f}"
                if zc
                else "–"
            )
            cl = ", ".join(f"{k} {v}" for k, v in what.most_common(3)) or "–"
            print(
                f"| {tc:g} | {tau:g} | {ok}/{n} | {found}/{n} | {med} | {rms} | {other}/{n} | {cl} | "
                f"{(time.process_time() - t0) / n:.1f} |",
                flush=True,
            )
    rows = [(tc, 300, p) for tc in PLAIN_TC] + [(0.0, 1000, m)]
    print("\n| null | recordings | plain named | thermal_lag claimed | other finding | which |")
    print("|---|---|---|---|---|---|")
    for tc, first, count in rows:
        if count <= 0:
            continue
        plain = lag = other = 0
        what = Counter[str]()
        for seed in range(first, first + count):
            d = diagnose_recording(lag_recording(tc, 0.0, seed))
            plain += plain_named(d, tc)
            lag += lag_finding(d) is not None
            extra = [e for e in other_claims(d, "temperature_bias" if tc else "") if e != "thermal_lag"]
            other += bool(extra)
            what.update(extra)
        label = f"plain temperature_bias {tc:g} m/s²/°C" if tc else "clean, cycling temperature"
        cl = ", ".join(f"{k} {v}" for k, v in what.most_common(3)) or "–"
        print(f"| {label} | {count} | {plain if tc else '–'} | {lag} | {other} | {cl} |", flush=True)


if __name__ == "__main__":
    a = sys.argv[1:]
    main(int(a[0]) if a else 4, int(a[1]) if len(a) > 1 else 20, int(a[2]) if len(a) > 2 else 10)
