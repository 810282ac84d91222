"""Speed of ``calbench diagnose`` on a simulated static-12 recording.

Times ``diagnose_recording`` (windows, window noise, REML slow noise, greedy selection,
refit) against ``calibrate_recording`` of the same recording in the same run (the ratio is
what matters; absolute seconds depend on the machine); and of a moving-table recording
(90 s two-axis oscillation at 100 Hz) against ``calibrate_recording`` (the dynamic batch
fit with its Kalman cross-check) of the same recording.
"""

from __future__ import annotations

import time

from bench.calibration import calibrate_recording
from bench.calibration.diagnose import diagnose_recording
from tests.support.diagnose_cases import static_recording
from tests.support.diagnose_dynamic_cases import moving_recording


def _best_of(fn, repeats: int = 3) -> float:  # type: ignore[no-untyped-def]
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    """Print the timings (module docstring)."""
    clean = static_recording({}, seed=7)
    found = static_recording({"nonlinearity_quadratic": {"k2_per_g": [0.0, 0.0, 2e-3]}}, seed=7)
    t_cal = _best_of(lambda: calibrate_recording(clean))
    t_clean = _best_of(lambda: diagnose_recording(clean))
    t_found = _best_of(lambda: diagnose_recording(found))
    print(f"static-12, 12 x 30 s at 100 Hz: calibrate {t_cal * 1e3:.0f} ms (baseline)")
    print(f"  diagnose, clean recording:        {t_clean * 1e3:.0f} ms = {t_clean / t_cal:.1f} x calibrate")
    print(f"  diagnose, one effect to be found:  {t_found * 1e3:.0f} ms = {t_found / t_cal:.1f} x calibrate")
    lever = {"lever_arm": {"r_m": [0.02, -0.01, 0.015]}}
    osc_clean, osc_found = moving_recording({}, seed=7), moving_recording(lever, seed=7)
    t_dcal = _best_of(lambda: calibrate_recording(osc_clean), repeats=2)
    t_dclean = _best_of(lambda: diagnose_recording(osc_clean), repeats=2)
    t_dfound = _best_of(lambda: diagnose_recording(osc_found), repeats=2)
    print(f"oscillation-2axis, 90 s at 100 Hz: calibrate {t_dcal * 1e3:.0f} ms (baseline)")
    print(f"  diagnose, clean:        {t_dclean * 1e3:.0f} ms = {t_dclean / t_dcal:.1f} x calibrate")
    print(f"  diagnose, lever arm:    {t_dfound * 1e3:.0f} ms = {t_dfound / t_dcal:.1f} x calibrate")


if __name__ == "__main__":
    main()
