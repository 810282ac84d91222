"""Cost of ``calibrate`` and ``diagnose`` against the number of static windows and of samples.

A clean simulated static run (``SensorTruth.typical``: white noise and a 200 s Gauss-Markov
bias wander; the 12-pose tumble repeated, 10 s windows, fast moves between them) is
calibrated and diagnosed at 12 … 3000 windows; then 12 windows with longer dwells (more
samples per window). Printed: seconds per call (wall, and the process's CPU time: on a
machine shared with other work the wall time is what the user waits, the CPU time what the
method costs), the findings (a clean run must give none),
the growth exponent a of t ∝ m^a fitted over the sweep (least squares in log-log), the
acceptance ratios t(192) / t(12) (≤ 4) and t(3000) (≤ 120 s on the project machine).

Run alone: ``python -m benchmarks window_count``; a shorter sweep with ``--quick`` as the
module's argument (``python -m benchmarks.bench_window_count --quick``).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import replace

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration import calibrate_recording
from bench.calibration.diagnose import diagnose_recording
from bench.recording import Recording
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth

WINDOWS = (12, 48, 192, 768, 3000)
QUICK_WINDOWS = (12, 48, 192)
DWELLS_S = (10.0, 40.0, 160.0)
RATE_HZ = 20.0


CHUNK_WINDOWS = 96
"""The simulator's motion profile costs O(samples × moves), so a long session is simulated in
chunks of this many windows, each starting at the pose where the previous one ended
(encoders continuous; that first hold is not a window). Each chunk has its own noise seed:
the bias wander restarts from its stationary distribution at every join."""


def static_session(
    n_windows: int, seed: int = 7, dwell_s: float = 10.0, rate_hz: float = RATE_HZ
) -> Recording:
    """A clean static run of ``n_windows`` windows (the 12-pose tumble repeated), fast moves."""
    reps = math.ceil(n_windows / 12)
    poses = np.tile(static12_poses_deg(), (reps, 1))[:n_windows]
    truth = SensorTruth.typical("V", seed=seed)
    t_parts, raw, enc, temp, segs = [], [], [], [], []
    t0 = 0.0
    first: Recording | None = None
    for c, start in enumerate(range(0, n_windows, CHUNK_WINDOWS)):
        chunk = poses[start : start + CHUNK_WINDOWS]
        if c:
            chunk = np.vstack([poses[start - 1], chunk])
        physics = SensorPhysics(truth, DEFAULT_AXES, seed=seed * 10007 + c)
        run = simulate_static(
            chunk, dwell_s, physics, rate_hz, move_rate_deg_s=180.0, move_accel_deg_s2=720.0
        )
        rec = to_recording(run, serial=f"SIM-{seed}")
        first = rec if first is None else first
        t_parts.append(rec.t_s + t0)
        raw.append(rec.accel_raw)
        enc.append(rec.table_deg)
        temp.append(rec.temp_c)
        for k, sg in enumerate(rec.sidecar.segments):
            if c and k == 0:
                continue
            segs.append(
                replace(sg, start_s=sg.start_s + t0, end_s=sg.end_s + t0, label=f"w{len(segs) + 1:04d}")
            )
        t0 = float(t_parts[-1][-1]) + 1.0 / rate_hz
    assert first is not None
    return replace(
        first,
        sidecar=replace(first.sidecar, segments=tuple(segs)),
        t_s=np.concatenate(t_parts),
        accel_raw=np.vstack(raw),
        table_deg=np.vstack(enc),
        temp_c=None if any(x is None for x in temp) else np.concatenate(temp),
    )


def _timed(fn):  # type: ignore[no-untyped-def]
    """(wall s, CPU s of this process, result): on a shared machine the two differ."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - t0, time.process_time() - c0, out


def growth_exponent(x: list[float], t: list[float]) -> float:
    """a of t ∝ x^a, least squares on log t = a log x + c."""
    return float(np.polyfit(np.log(x), np.log(t), 1)[0])


def main(windows: tuple[int, ...] = WINDOWS) -> None:
    """Print the sweep (module docstring)."""
    print(f"static run, 10 s windows at {RATE_HZ:.0f} Hz, clean (white noise + 200 s bias wander)")
    print(
        f"{'windows':>8} {'samples':>9} {'calibrate s':>12} {'(cpu s)':>8} "
        f"{'diagnose s':>11} {'(cpu s)':>8}  findings"
    )
    t_cal: list[float] = []
    t_diag: list[float] = []
    for m in windows:
        rec = static_session(m)
        tc, cc, _ = _timed(lambda rec=rec: calibrate_recording(rec))
        td, cd, d = _timed(lambda rec=rec: diagnose_recording(rec))
        t_cal.append(tc)
        t_diag.append(td)
        found = ", ".join(f.effect for f in d.findings) or "none"
        print(f"{m:8d} {rec.t_s.size:9d} {tc:12.2f} {cc:8.2f} {td:11.2f} {cd:8.2f}  {found}", flush=True)
    ms = [float(m) for m in windows]
    print(
        f"growth exponent (t ∝ m^a): calibrate a = {growth_exponent(ms, t_cal):.2f}, "
        f"diagnose a = {growth_exponent(ms, t_diag):.2f}"
    )
    if 12 in windows and 192 in windows:
        r = t_diag[windows.index(192)] / t_diag[windows.index(12)]
        print(f"diagnose t(192) / t(12) = {r:.1f} (acceptance <= 4)")
    if 3000 in windows:
        print(f"diagnose t(3000) = {t_diag[windows.index(3000)]:.0f} s (acceptance <= 120 s)")
    print(f"12 windows, longer dwells at {RATE_HZ:.0f} Hz (samples per window):")
    n_s, t_s = [], []
    for dwell in DWELLS_S:
        rec = static_session(12, dwell_s=dwell)
        td, _, d = _timed(lambda rec=rec: diagnose_recording(rec))
        n_s.append(float(rec.t_s.size))
        t_s.append(td)
        found = ", ".join(f.effect for f in d.findings) or "none"
        print(f"  dwell {dwell:5.0f} s, {rec.t_s.size:7d} samples: diagnose {td:.2f} s  {found}", flush=True)
    print(f"growth exponent in samples (t ∝ n^a): diagnose a = {growth_exponent(n_s, t_s):.2f}")


if __name__ == "__main__":
    main(QUICK_WINDOWS if "--quick" in sys.argv[1:] else WINDOWS)
