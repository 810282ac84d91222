"""Clean recordings of every kind through ``diagnose`` and ``calibrate``: the false-claim rates
and whether ``calibrate`` fits only terms the diagnosis claims (docs/diagnose.md, clean rates).

``python -m benchmarks.study_clean_rates KIND N [FIRST_SEED]``: N clean simulated recordings
of one kind, seeds FIRST_SEED… (default 5000):

- ``static-12``: the 12-pose tumble of ``tests.support.diagnose_cases.static_recording``;
- ``oscillation``, ``rate``: the 90 s two-axis oscillation and the 73 s rate-1axis run of
  ``tests.support.diagnose_dynamic_cases.moving_recording`` (100 Hz);
- ``tumble``: the planner's every-sample tumble of ``benchmarks.study_sigmas_moving`` (3 min
  of table time, moves included, 50 Hz), recorded as ``planned-tumble`` so that both
  ``diagnose`` and ``calibrate`` treat it as a moving recording;
- ``hand-held``: 24 random orientations without table columns
  (``benchmarks.study_diagnose_one_channel.hand_held``), diagnosed orientation-free.

Per recording with a claim or a fitted term, one line (and one per seed the simulator refuses,
which is left out of N); then one markdown row: recordings with a
catalogue finding, with a discovered term, with ``unexplained``, with any of these, and
``calibrate`` violations: recordings where a term beyond bias and K that ``calibrate`` fits
(``DynamicCalibrationResult.model_terms``, chosen by ``model_selection``) is not among the
diagnosis's findings. A static or orientation-free fit has no term beyond bias and K, so it
cannot violate; the column is counted all the same.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace

from bench.calibration.diagnose import diagnose_recording
from bench.calibration.recording import calibrate_recording
from bench.recording import Recording

KINDS = ("static-12", "oscillation", "rate", "tumble", "hand-held")
HEADER = (
    "| clean recordings | seeds | N | finding | discovered term | unexplained | any | "
    "calibrate fits a term not claimed |\n|---|---|---|---|---|---|---|---|"
)


def recording(kind: str, seed: int) -> Recording:
    """One clean recording of ``kind`` (module docstring)."""
    if kind == "static-12":
        from tests.support.diagnose_cases import static_recording

        return static_recording({}, seed=seed)
    if kind in ("oscillation", "rate"):
        from tests.support.diagnose_dynamic_cases import moving_recording

        return moving_recording({}, seed, kind=kind)
    if kind == "tumble":
        from api.simulated_recording import to_recording
        from benchmarks.study_sigmas_moving import simulate

        rec = to_recording(simulate("tumble", "clean", seed), serial=f"SIM-TUMBLE-{seed}")
        return replace(rec, sidecar=replace(rec.sidecar, procedure="planned-tumble"))
    if kind == "hand-held":
        from benchmarks.study_diagnose_one_channel import hand_held, tableless

        return tableless(hand_held(seed))
    raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")


def calibrate_terms(rec: Recording) -> tuple[str, ...]:
    """The terms beyond bias and K that ``calibrate`` fits to ``rec`` (none for a window fit)."""
    fit = calibrate_recording(rec)
    return tuple(getattr(fit, "model_terms", ()))


def main(kind: str, n: int, first: int) -> None:
    """Print the lines and the row of the module docstring."""
    fin = dis = unx = anyc = bad = 0
    skipped: list[int] = []
    t0 = time.process_time()
    for seed in range(first, first + n):
        try:
            rec = recording(kind, seed)
        except ValueError as exc:  # the simulator refuses a move (a hand-held seed now and then)
            print(f"{kind} {seed}: not simulated: {exc}", flush=True)
            skipped.append(seed)
            continue
        d = diagnose_recording(rec)
        found = [f.effect for f in d.findings]
        disc = [f"{x.term}[{x.channel}]" for x in d.discovered]
        fitted = calibrate_terms(rec)
        extra = [t for t in fitted if t not in found]
        fin += bool(found)
        dis += bool(disc)
        unx += d.unexplained is not None
        anyc += bool(found or disc or d.unexplained is not None)
        bad += bool(extra)
        if found or disc or d.unexplained is not None or fitted:
            un = "" if d.unexplained is None else f", unexplained on {d.unexplained.channel}"
            print(
                f"{kind} {seed}: findings {found}, discovered {disc}{un}; calibrate fits {list(fitted)}",
                flush=True,
            )
    cpu, done = time.process_time() - t0, n - len(skipped)
    each = cpu / max(done, 1)
    print(f"# {done} recordings ({skipped} not simulated), {cpu:.0f} CPU s ({each:.1f} s each)")
    print(HEADER)
    print(
        f"| {kind} | {first}–{first + n - 1} | {done} | {fin} | {dis} | {unx} | {anyc} | {bad} |", flush=True
    )


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 5000)
