"""One channel carrying the misfit, static and hand-held (docs/diagnose.md, "Not yet done").

``python -m benchmarks.study_diagnose_one_channel [N]``: N seeds (100…) of each row. Recordings:
the typical ADXL-like triad of ``tests.support.diagnose_cases`` (V, 100 Hz, 250 µg/√Hz, 40 µg
wander), 30 s windows; ``hand-held`` is 24 random orientations (uniform on the sphere) with the
table columns removed, so the diagnosis is orientation-free; ``static-12`` is the 12-pose tumble.
A cubic c·f_x³ (V per g³) is added to ax (``benchmarks.library_cases.conceal``). For each row
prints how many recordings gave a catalogue finding, a discovered term, an ``unexplained``
block, and ``unexplained`` naming the truth's channel as the one with the largest χ² ratio.
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration.diagnose import diagnose_recording
from bench.recording import Recording
from benchmarks.library_cases import conceal, specific_force_g
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


def row(kind: str, c_v_per_g3: float, seeds: range, channel: int = 0) -> str:
    """One table row: counts over the seeds."""
    fin = dis = unx = right = 0
    for s in seeds:
        if kind == "hand-held":
            rec = tableless(cubic(hand_held(s), channel, c_v_per_g3))
        else:
            rec = cubic(static_recording({}, s), channel, c_v_per_g3)
        d = diagnose_recording(rec)
        fin += bool(d.findings)
        dis += bool(d.discovered)
        u = d.unexplained
        unx += u is not None
        if u is not None and u.channels:
            right += max(u.channels, key=lambda k: u.channels[k]) == CHANNELS[channel]
    return f"| {kind} | {c_v_per_g3:g} | {len(seeds)} | {fin} | {dis} | {unx} | {right} |"


def main(n: int) -> None:
    """Print the table of the module docstring."""
    seeds = range(100, 100 + n)
    print("| recording | cubic on ax (V/g³) | N | finding | discovered | unexplained | on ax |")
    print("|---|---|---|---|---|---|---|")
    for kind, c in (("hand-held", 0.0), ("hand-held", 1e-3), ("hand-held", 4e-3), ("static-12", 2e-4)):
        print(row(kind, c, seeds), flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
