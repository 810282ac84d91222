"""Clean recordings through ``diagnose``: false claims, and text against JSON (docs/diagnose.md).

``python -m benchmarks.study_diagnose_clean [N_STATIC] [N_MOVING]``: N_STATIC clean simulated
static-12 recordings (``tests.support.diagnose_cases.static_recording``, seeds 2000…) and
N_MOVING clean two-axis oscillations (``moving_recording``, seeds 3000…); for each kind prints
how many gave a catalogue finding, a discovered term, an ``unexplained`` block, and how many
had text and JSON that disagree (the checks of ``tests/api/cli/test_cli_diagnose_agreement.py``).
"""

from __future__ import annotations

import sys
from collections.abc import Callable

from api.cli.diagnose import format_human
from bench.calibration.diagnose import diagnose_recording
from bench.recording import Recording
from tests.support.diagnose_cases import static_recording
from tests.support.diagnose_dynamic_cases import moving_recording


def disagrees(text: str, js: dict[str, object]) -> bool:
    """Whether the text contradicts the JSON (a claim beside "nowhere beyond the noise", a
    finding or UNEXPLAINED line in one and not the other)."""
    claims = bool(js["findings"] or js["discovered"] or "unexplained" in js)
    found = [line.split(":")[0][6:] for line in text.splitlines() if line.startswith("FOUND ")]
    return (
        (claims and "nowhere beyond the noise" in text)
        or (("UNEXPLAINED" in text) != ("unexplained" in js))
        or found != [f["effect"] for f in js["findings"]]  # type: ignore[attr-defined, index]
    )


def row(kind: str, make: Callable[[int], Recording], seeds: range) -> str:
    """One table row: counts over the seeds."""
    fin = dis = unx = bad = 0
    for s in seeds:
        d = diagnose_recording(make(s))
        js = d.to_contract()
        fin += bool(d.findings)
        dis += bool(d.discovered)
        unx += d.unexplained is not None
        bad += disagrees(format_human(d), js)
    n = len(seeds)
    return f"| {kind} | {n} | {fin} | {dis} | {unx} | {bad} |"


def main(n_static: int, n_moving: int) -> None:
    """Print the table of the module docstring."""
    print("| clean recordings | N | with a finding | with a discovered term | unexplained | text ≠ JSON |")
    print("|---|---|---|---|---|---|")
    print(row("static-12", lambda s: static_recording({}, s), range(2000, 2000 + n_static)), flush=True)
    print(
        row("oscillation-2axis", lambda s: moving_recording({}, s), range(3000, 3000 + n_moving)), flush=True
    )


if __name__ == "__main__":
    a = [int(x) for x in sys.argv[1:]]
    main(a[0] if a else 40, a[1] if len(a) > 1 else 6)
