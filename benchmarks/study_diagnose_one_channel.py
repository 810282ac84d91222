"""One channel carrying the misfit, static and hand-held (docs/diagnose.md).

``python -m benchmarks.study_diagnose_one_channel [N] [ROWS]``: N seeds (100…) of each row
(ROWS: comma-separated row numbers, default all). Recordings: the typical ADXL-like triad of
``tests.support.diagnose_cases`` (V, 100 Hz, 250 µg/√Hz, 40 µg wander), 30 s windows;
``hand-held`` is 24 random orientations (uniform on the sphere) with the table columns removed,
so the diagnosis is orientation-free; ``static-12`` is the 12-pose tumble. Added to ax
(``benchmarks.library_cases.conceal``): a cubic c·f_x³ (V per g³), or a loose connector, an
offset of c V rms that changes at random from window to window (``window_offsets``).
Columns per row: recordings with a catalogue finding; with a discovered term; with the
truth's term discovered on ax within 3 σ of c (cubic) or named among its look-alikes; with
``unexplained``; with ``unexplained`` naming ax as the channel that carries the misfit
(``Unexplained.channel``); with a channel named that is not ax; and the acceptance's count,
recordings with no catalogue finding where the truth is discovered or ax is named.
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration.diagnose import diagnose_recording
from bench.recording import Recording
from benchmarks.library_cases import conceal, specific_force_g, window_offsets
from drivers.sim.offline import DEFAULT_AXES, simulate_static
from drivers.sim.physics import SensorPhysics, SensorTruth
from tests.support.diagnose_cases import static_recording

CHANNELS = ("ax", "ay", "az")


def hand_held(seed: int, m: int = 24) -> Recording:
    """A clean simulated session of m random orientations, without table columns."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x4A4D]))
    poses = np.column_stack(
        [
            rng.uniform(-180.0, 180.0, m),
            np.degrees(np.arccos(rng.uniform(-1.0, 1.0, m))),
            rng.uniform(-180.0, 180.0, m),
        ]
    )
    truth = SensorTruth.typical("V", seed=seed)
    run = simulate_static(poses, 30.0, SensorPhysics(truth, DEFAULT_AXES, seed=seed), 100.0)
    return to_recording(run, serial=f"SIM-{seed}")


def tableless(rec: Recording) -> Recording:
    """The recording without its table: orientation-free evidence."""
    return replace(rec, table_deg=None, sidecar=replace(rec.sidecar, table=None))


def cubic(rec: Recording, channel: int, c_v_per_g3: float) -> Recording:
    """``rec`` with c·f³ of its own axis added to ``channel``."""
    if c_v_per_g3 == 0.0:
        return rec
    return conceal(rec, channel, specific_force_g(rec)[:, channel] ** 3, c_v_per_g3)


def loose(rec: Recording, channel: int, c_v: float) -> Recording:
    """``rec`` with a loose connector of c_v V rms on ``channel``."""
    if c_v == 0.0:
        return rec
    return conceal(rec, channel, window_offsets(rec), c_v)


ROWS: tuple[tuple[str, str, float], ...] = (
    ("static-12", "clean", 0.0),
    ("static-12", "loose", 5e-5),
    ("static-12", "loose", 1e-4),
    ("static-12", "loose", 2e-4),
    ("static-12", "cubic", 2e-4),
    ("hand-held", "clean", 0.0),
    ("hand-held", "cubic", 1e-3),
    ("hand-held", "cubic", 4e-3),
    ("hand-held", "loose", 1e-4),
    ("hand-held", "loose", 2e-4),
)
"""(recording, what is added to ax, its size c) of each row."""


def recording(kind: str, what: str, c: float, seed: int, channel: int = 0) -> Recording:
    """One recording of a row."""
    if kind == "hand-held":
        rec = hand_held(seed)
        # the effect is added while the table columns still say where each sample pointed
        return tableless(cubic(rec, channel, c) if what == "cubic" else loose(rec, channel, c))
    rec = static_recording({}, seed)
    return cubic(rec, channel, c) if what == "cubic" else loose(rec, channel, c)


def row(kind: str, what: str, c: float, seeds: range, channel: int = 0) -> str:
    """One table row: counts over the seeds."""
    fin = dis = right = unx = named = wrong = clean_right = 0
    skipped = []
    for s in seeds:
        try:
            rec = recording(kind, what, c, s, channel)
        except ValueError:  # the simulator cannot make this pose sequence: said, not hidden
            skipped.append(s)
            continue
        d = diagnose_recording(rec)
        fin += bool(d.findings)
        dis += bool(d.discovered)
        found = False
        for x in d.discovered:
            if what == "cubic" and x.channel == CHANNELS[channel]:
                exact = x.term == f"f_{'xyz'[channel]}^3" and abs(x.coefficient - c) <= 3.0 * x.sigma
                found = found or exact or f"f_{'xyz'[channel]}^3" in x.confounded_with
        right += found
        u = d.unexplained
        unx += u is not None
        if u is not None and u.channel is not None:
            named += u.channel == CHANNELS[channel]
            wrong += u.channel != CHANNELS[channel]
        flagged = u is not None and u.channel == CHANNELS[channel]
        clean_right += not d.findings and (found or flagged)
    n = len(seeds) - len(skipped)
    note = f" (seeds {', '.join(map(str, skipped))}: not simulated)" if skipped else ""
    counts = " | ".join(str(k) for k in (fin, dis, right, unx, named, wrong, clean_right))
    return f"| {kind} | {what} | {c:g} | {n}{note} | {counts} |"


def main(n: int, rows: list[int]) -> None:
    """Print the table of the module docstring."""
    seeds = range(100, 100 + n)
    cols = ("recording", "on ax", "c", "N", "finding", "discovered", "truth discovered", "unexplained")
    print("| " + " | ".join((*cols, "names ax", "names another", "no finding, truth or ax")) + " |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for k in rows:
        print(row(*ROWS[k], seeds), flush=True)


if __name__ == "__main__":
    n_seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    chosen = [int(k) for k in sys.argv[2].split(",")] if len(sys.argv) > 2 else list(range(len(ROWS)))
    main(n_seeds, chosen)
