"""Cost of the moving library: ``diagnose`` of simulated oscillations of growing length, with
and without the library (``diagnose_dynamic(..., library=False)``), interleaved in one process.

Recordings: the typical triad at 100 Hz (``tests.support.diagnose_dynamic_cases``), the
two-axis oscillation of ``duration_s`` = 90, 300 and 900 s, clean and with ax delayed 5 ms
(the simulator's delay taken for ax alone: the library finds fdot_x on ax and cuts the
catalogue's path, the most expensive case). Best of ``repeats`` wall times per cell.

Run: ``python -m benchmarks.bench_diagnose_moving [repeats]``.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration.windows import moving_samples
from bench.diagnosis.dynamic import diagnose_dynamic
from bench.recording import Recording
from drivers.sim.offline import DEFAULT_AXES, simulate_oscillation
from drivers.sim.physics import SensorPhysics, SensorTruth


def oscillation(duration_s: float, seed: int, effects: dict[str, dict[str, Any]]) -> Recording:
    """The 100 Hz two-axis oscillation of ``duration_s`` with ``effects`` concealed."""
    truth = SensorTruth.typical("V", seed=seed).with_effects(effects)
    run = simulate_oscillation(SensorPhysics(truth, DEFAULT_AXES, seed=seed), 100.0, duration_s=duration_s)
    return to_recording(run, serial=f"SIM-DYN-{seed}")


def delayed_ax(duration_s: float, seed: int) -> Recording:
    """ax 5 ms behind ay, az (the simulator's delay, taken for ax only)."""
    clean = oscillation(duration_s, seed, {})
    raw = clean.accel_raw.copy()
    raw[:, 0] = oscillation(duration_s, seed, {"time_skew": {"delay_s": 0.005}}).accel_raw[:, 0]
    return replace(clean, accel_raw=raw)


def _timed(fn: Callable[[], object], repeats: int) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 2
    print("duration  samples  case     without library s  with library s  ratio  discovered")
    for duration in (90.0, 300.0, 900.0):
        for case, rec in (("clean", oscillation(duration, 7, {})), ("ax 5 ms", delayed_ax(duration, 7))):
            m, y = moving_samples(rec)
            geo = rec.sidecar.table
            assert geo is not None
            lever = np.asarray(geo.lever_arm_m, dtype=float)

            def run(library: bool, m=m, y=y, lever=lever, rec=rec) -> object:  # type: ignore[no-untyped-def]
                return diagnose_dynamic(
                    m, y, rec.sidecar.g_local_m_s2, lever, temp_c=rec.temp_c, library=library
                )

            t_off, _ = _timed(lambda: run(False), repeats)
            t_on, d = _timed(lambda: run(True), repeats)
            found = ", ".join(f"{x.term}[{x.channel}]" for x in d.discovered) or "none"  # type: ignore[attr-defined]
            cells = f"{t_off:17.2f}  {t_on:14.2f}  {t_on / t_off:5.1f}"
            print(f"{duration:6.0f} s  {m.n:7d}  {case:7s}  {cells}  {found}")


if __name__ == "__main__":
    main()
