"""Out-of-catalogue physics table of ``calbench diagnose`` (docs/diagnose.md, "Beyond the catalogue").

``python -m benchmarks.study_diagnose_library [N] [M]``: for each scenario of
``benchmarks.library_cases.CASES``, N simulated static-12 recordings (seeds 100…) with the
term concealed; prints, as a markdown table, how often the term was named on its channel,
how often a term it cannot be told from on this pose set was named instead (the truth in
that term's ``confounded_with``), |z| of the coefficient where named (median / max), how
many recordings claimed a catalogue effect or a pose error, and how many carried an
``unexplained`` block. Then M clean recordings (seeds 1000…): recordings with any
catalogue finding or discovered term; the time of ``diagnose`` with and without the
library on the first 10 of them (same evidence, same process, interleaved); and what each
example recording gives: the independent simulator's in ``tests/data/independent`` and the
shipped ones in ``examples/``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from bench.calibration.diagnose import diagnose_recording, recording_evidence
from bench.diagnosis import Diagnosis, diagnose
from bench.recording import read_recording
from benchmarks.library_cases import CASES, LibraryCase, score
from tests.support.diagnose_cases import static_recording

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "tests" / "data" / "independent"
"""The independent simulator's recordings (tests/data/independent/README.md)."""
SHIPPED = ROOT / "examples"


def row(case: LibraryCase, n: int) -> str:
    """One table row."""
    named = alike = cat = pose = unexp = 0
    zs = []
    ch = ("ax", "ay", "az")[case.channel]
    for seed in range(100, 100 + n):
        d = diagnose_recording(case.recording(seed))
        s = score(case, d)
        named += s.named
        if s.named:
            zs.append(abs(s.z))
        elif case.term and any(x.channel == ch and case.term in x.confounded_with for x in d.discovered):
            alike += 1
        cat += bool([e for e in s.catalogue if e != "pose_error"])
        pose += "pose_error" in s.catalogue
        unexp += s.unexplained
    z = f"{np.median(zs):.1f} / {np.max(zs):.1f}" if zs else "–"
    return (
        f"| {case.name} | {case.term or '(not expressible)'} on {ch} | {case.coefficient:.2g} | "
        f"{named}/{n} | {alike}/{n} | {z} | {cat}/{n} | {pose}/{n} | {unexp}/{n} |"
    )


def claims(d: Diagnosis) -> list[str]:
    """Catalogue findings and discovered terms of a diagnosis."""
    return [f.effect for f in d.findings] + [f"{x.term}[{x.channel}]" for x in d.discovered]


def main(argv: list[str] | None = None) -> None:
    """Print the study (module docstring)."""
    args = sys.argv[1:] if argv is None else argv
    n = int(args[0]) if args else 6
    m = int(args[1]) if len(args) > 1 else 200
    independent = sorted(EXAMPLES.glob("*.csv"))
    if not independent:  # checked first: the table takes minutes
        raise FileNotFoundError(f"{EXAMPLES}: no recordings (tests/data/independent/README.md)")
    t0 = time.perf_counter()
    print(
        "| scenario | truth | coefficient (V per unit) | named | alike named | abs z (median / max) | "
        "catalogue claimed | pose_error claimed | unexplained |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for case in CASES.values():
        print(row(case, n), flush=True)
    false: dict[int, list[str]] = {}
    unexplained = 0
    t_lib = t_cat = 0.0
    for seed in range(1000, 1000 + m):
        rec = static_recording({}, seed)
        d = diagnose_recording(rec)
        unexplained += d.unexplained is not None
        if claims(d):
            false[seed] = claims(d)
        if seed < 1010:
            ev = recording_evidence(rec)
            for lib in (False, True):
                a = time.perf_counter()
                diagnose(ev, use_library=lib)
                dt = time.perf_counter() - a
                t_lib, t_cat = (t_lib + dt, t_cat) if lib else (t_lib, t_cat + dt)
    print(f"clean: {len(false)} of {m} recordings with a finding or a discovered term {false}")
    print(f"clean: {unexplained} of {m} with an unexplained block")
    print(f"diagnose time with / without the library (10 clean recordings): {t_lib / t_cat:.2f}")
    for path in [*independent, *sorted(SHIPPED.glob("*.csv"))]:
        d = diagnose_recording(read_recording(path))
        u = d.unexplained.where if d.unexplained else "none"
        found = [f.summary for f in d.findings]
        print(f"{path.stem}: findings {found}, discovered {claims(d)[len(found) :]}, unexplained {u}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
