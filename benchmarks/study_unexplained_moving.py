"""``unexplained`` on simulated moving recordings: false alarms on clean ones, detection of a
concealed misfit outside every library on the right channel (docs/diagnose.md).

``python -m benchmarks.study_unexplained_moving [N]``: N clean rate-table and N clean oscillation
recordings (seeds 1000…; the simulator's bias wander included) and, on the same kinds, N recordings
(seeds 2000…) with a misfit added to one channel's samples (the channel turns with the seed):

- ``step``: a bias step at a time drawn in the middle half of the run;
- ``slow``: a sinusoid of period 30 s (a slow coherent disturbance).

Sizes are in block sigmas σ_b = σ_w / √(samples per 1 s block), σ_w the channel's white sigma
from its first differences. Prints, per row, how many recordings have ``unexplained`` (and on the
injected channel) and how many have a finding.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace

import numpy as np

from bench.calibration.diagnose import diagnose_recording
from bench.recording.model import Recording
from tests.support.diagnose_dynamic_cases import moving_recording

CHANNELS = ("ax", "ay", "az")
KINDS = ("rate", "oscillation")
MISFITS = (("step", 4.0), ("step", 8.0), ("slow", 3.0), ("slow", 6.0))


def concealed(rec: Recording, shape: str, size_block_sigma: float, channel: int, seed: int) -> Recording:
    """``rec`` with the misfit ``shape`` of ``size_block_sigma`` σ_b added to ``channel``."""
    y = np.array(rec.accel_raw, dtype=float)
    t = np.asarray(rec.t_s, dtype=float) - float(rec.t_s[0])
    rate_hz = (t.size - 1) / float(t[-1])
    sig_b = float(np.std(np.diff(y[:, channel])) / np.sqrt(2.0)) / np.sqrt(rate_hz)
    rng = np.random.default_rng(seed)
    if shape == "step":
        t0 = float(rng.uniform(0.25, 0.75)) * float(t[-1])
        y[:, channel] += size_block_sigma * sig_b * (t >= t0)
    else:
        y[:, channel] += size_block_sigma * sig_b * np.sin(2 * np.pi * t / 30.0 + rng.uniform(0, 2 * np.pi))
    return replace(rec, accel_raw=y)


def named_channel(d: object) -> str | None:
    """The channel ``unexplained`` names, or ``None`` when it is silent."""
    u = d.unexplained  # type: ignore[attr-defined]
    return None if u is None else str(u.where.split(":")[0])


def main(argv: list[str] | None = None) -> None:
    """Print the table (module docstring)."""
    args = sys.argv[1:] if argv is None else argv
    n = int(args[0]) if args else 4
    t0 = time.perf_counter()
    print("| recording | misfit | unexplained | on the injected channel | with a finding |")
    print("|---|---|---|---|---|")
    for kind in KINDS:
        said = found = 0
        for seed in range(1000, 1000 + n):
            d = diagnose_recording(moving_recording({}, seed, kind=kind))
            said += named_channel(d) is not None
            found += bool(d.findings or d.discovered)
        print(f"| clean {kind} | none | {said}/{n} | – | {found}/{n} |", flush=True)
        for shape, size in MISFITS:
            said = right = found = 0
            for seed in range(2000, 2000 + n):
                c = seed % 3
                rec = concealed(moving_recording({}, seed, kind=kind), shape, size, c, seed)
                d = diagnose_recording(rec)
                ch = named_channel(d)
                said += ch is not None
                right += ch == CHANNELS[c]
                found += bool(d.findings or d.discovered)
            print(
                f"| {kind} | {shape} {size:g} sigma_b | {said}/{n} | {right}/{n} | {found}/{n} |", flush=True
            )
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
