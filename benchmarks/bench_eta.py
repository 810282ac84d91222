"""How well the run's remaining time is predicted: simulated runs of each service procedure.

Each procedure runs on the simulated bench at ``SPEED`` × real time (the service's simulator,
its dwell chosen from the noise window); every progress event is kept. The truth is the end of
the recording on the bench clock (the last window's end or the last event, whichever is
later); at the first event past 25 % and 50 % of it, the predicted remaining time
(:class:`bench.sequencer.progress.RemainingTime`: the remaining nominal durations scaled by
the measured ratio of actual to nominal time) is compared with the true remaining time, and so
is the preview's estimate alone (preview duration minus time so far). Target: within 15 %.
Printed per procedure and seed: the recording's length, the preview's duration, both errors
at 25 % and 50 %. ``python -m benchmarks.bench_eta --speed 5 --seeds 1 2 3`` runs at another
simulation speed (the table's wall-clock round trips, which the machine's load stretches, count
``speed`` times on the bench clock) or with other seeds.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from bench.procedures import build_procedure, preview
from bench.records import Progress
from bench.run_observer import NullObserver
from station.execution.session import start_run
from station.settings import Settings

SPEED = 20.0
RATE_HZ = 250.0
PROCEDURES = ("static-12", "rate-1axis", "oscillation-2axis")
SEEDS = (1, 2)
TARGET = 0.15
POINTS = (0.25, 0.5)


class Events(NullObserver):
    """Keeps (recording clock, predicted remaining) of every progress event."""

    def __init__(self) -> None:
        self.events: list[tuple[float, float]] = []

    def on_progress(self, run_id: str, progress: Progress) -> None:
        self.events.append((progress.elapsed_s, progress.expected_total_s - progress.elapsed_s))


def one_run(
    tmp: Path, name: str, seed: int, speed: float = SPEED, points: tuple[float, ...] = POINTS
) -> tuple[float, float, list[tuple[float, float, float]]]:
    """(recording length s, preview s, [(fraction, predicted error, preview error)] at each of
    ``points``, fractions of the recording)."""
    settings = Settings(data_dir=tmp / f"{name}-{seed}", sim_sample_rate_hz=RATE_HZ)
    obs = Events()
    record = start_run(
        settings, name, f"SN-ETA-{seed}", sim=True, sim_speed=speed, seed=seed, observers=[obs], limits=None
    )
    if record.error:
        raise RuntimeError(f"{name} seed {seed}: {record.error}")
    end_s = max(record.windows[-1].end_s, obs.events[-1][0])
    preview_s = preview(build_procedure(name), sample_rate_hz=RATE_HZ).duration_s
    out = []
    for frac in points:
        t, predicted = next((t, p) for t, p in obs.events if t >= frac * end_s)
        truth = end_s - t
        out.append((frac, (predicted - truth) / truth, (preview_s - t - truth) / truth))
    return end_s, preview_s, out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_eta")
    parser.add_argument("--speed", type=float, default=SPEED, help="simulation speed (x real time)")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS))
    parser.add_argument("--procedures", nargs="+", default=list(PROCEDURES))
    parser.add_argument("--points", type=float, nargs="+", default=list(POINTS), help="fractions of the run")
    args = parser.parse_args(argv or [])
    points = tuple(args.points)
    print(f"simulated bench at ×{args.speed:g}, {RATE_HZ:g} Hz; error = (predicted − true) / true remaining")
    heads = "   ".join(f"{f'at {100 * f:g} %':>8} {'preview':>8}" for f in points)
    print(f"{'procedure':<18} {'seed':>4} {'recording':>10} {'preview':>8}   {heads}")
    worst = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.procedures:
            for seed in args.seeds:
                end_s, preview_s, rows = one_run(Path(tmp), name, seed, args.speed, points)
                cells = "   ".join(f"{100 * e:+7.1f} % {100 * p:+7.1f} %" for _, e, p in rows)
                print(f"{name:<18} {seed:>4} {end_s:>8.0f} s {preview_s:>6.0f} s   {cells}", flush=True)
                worst = max(worst, *(abs(e) for _, e, _ in rows))
    met = "met" if worst <= TARGET else "NOT met"
    print(f"largest |error| of the prediction: {100 * worst:.1f} % (target {100 * TARGET:.0f} %: {met})")


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
