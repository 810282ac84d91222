"""What the excess carried into the selection's noise changes (docs/diagnose.md, the head to
head with "unexplained on one channel").

``python -m benchmarks.study_carried_excess loose``: the loose connector
(``benchmarks.library_cases``, ``CASES["loose_connector"]``) at 1e-4 on seeds 100–105 and at
2e-4 on seeds 100–101, one line each: the claims (catalogue findings and discovered terms),
the channel ``unexplained`` names and the CPU time.

``python -m benchmarks.study_carried_excess clean LO HI``: clean static-12 recordings of seeds
LO…HI−1 (``tests.support.diagnose_cases.static_recording``, the recordings of
``test_false_findings_on_two_hundred_clean_recordings_count_discovered_terms`` for 1000 1200):
one line per recording with a claim, then how many had one.
"""

from __future__ import annotations

import sys
import time

from bench.calibration.diagnose import diagnose_recording
from bench.diagnosis import Diagnosis


def claims(d: Diagnosis) -> list[str]:
    """Catalogue findings and discovered terms (``term[channel]``)."""
    return [f.effect for f in d.findings] + [f"{x.term}[{x.channel}]" for x in d.discovered]


def loose() -> None:
    """The loose connector's lines."""
    from benchmarks.library_cases import CASES

    case = CASES["loose_connector"]
    for seed, size in [*((s, 1.0) for s in range(100, 106)), (100, 2.0), (101, 2.0)]:
        t0 = time.process_time()
        d = diagnose_recording(case.recording(seed, size))
        named = None if d.unexplained is None else d.unexplained.channel
        print(
            f"loose connector {size * case.coefficient:.0e}, seed {seed}: claims {claims(d)}, "
            f"unexplained names {named}, {time.process_time() - t0:.1f} CPU s",
            flush=True,
        )


def clean(lo: int, hi: int) -> None:
    """The clean recordings' lines."""
    from tests.support.diagnose_cases import static_recording

    false: dict[int, list[str]] = {}
    for seed in range(lo, hi):
        found = claims(diagnose_recording(static_recording({}, seed=seed)))
        if found:
            false[seed] = found
            print(f"clean {seed}: {found}", flush=True)
    print(f"clean {lo}-{hi - 1}: {len(false)} of {hi - lo} with a claim: {false}", flush=True)


if __name__ == "__main__":
    if sys.argv[1] == "loose":
        loose()
    else:
        clean(int(sys.argv[2]), int(sys.argv[3]))
