"""Dynamic calibration: batch fit and Kalman filter on oscillation recordings, against numpy.

Recordings: the oscillation-2axis run (simulated ADXL325-like unit with a lever arm, a
tilted base and a 2 ms time skew), 3 minutes at 100 Hz and 10 minutes at 1 kHz.
Baseline, measured in the same run on the same samples: one ``np.linalg.lstsq`` of the
raw samples on [1 f] with f from the believed geometry (a linear fit of bias and K with
no lever arm, no covariance). Reported: the motion regressors (Savitzky–Golay derivatives,
attitude chain), the batch Gauss-Newton fit with its sandwich covariance, and the
extended Kalman filter (two passes, 0.1 s batches), each as seconds and as a multiple of
the baseline. Set OPENBLAS_NUM_THREADS=1 on a shared machine: the Gram products are small
and threads only contend.
"""

from __future__ import annotations

import time

import numpy as np

from api.simulated_recording import to_recording
from bench.estimation.dynamic_batch import fit_dynamic_batch, linear_start
from bench.estimation.dynamic_kalman import run_dynamic_kalman
from bench.estimation.dynamic_model import ModelSpec, initial_theta, specific_force
from bench.estimation.motion_data import prepare_motion
from drivers.sim.offline import DEFAULT_AXES, simulate_oscillation
from drivers.sim.physics import SensorPhysics, SensorTruth

CASES = (("3 min at 100 Hz", 180.0, 100.0), ("10 min at 1 kHz", 600.0, 1000.0))
TERMS = ("lever_arm", "table_tilt", "time_skew")


def _case(label: str, duration_s: float, rate_hz: float) -> None:
    truth = SensorTruth.typical("V", seed=5).with_effects(
        {
            "lever_arm": {"r_m": [0.05, -0.02, 0.03]},
            "table_tilt": {"tilt_rad": [2e-4, -3e-4]},
            "time_skew": {"delay_s": 2e-3},
        }
    )
    run = simulate_oscillation(SensorPhysics(truth, DEFAULT_AXES, seed=2), rate_hz, duration_s=duration_s)
    rec = to_recording(run, serial="SN-BENCH")
    q = rec.table_rad_unwrapped()
    assert q is not None
    t0 = time.perf_counter()
    m = prepare_motion(rec.t_s, q, run.axis_vectors, np.eye(3))
    t_prep = time.perf_counter() - t0
    spec0 = ModelSpec(())
    f = specific_force(
        initial_theta(spec0, np.zeros(3), np.eye(3), np.zeros(3)), m, spec0, run.g_local_m_s2, np.zeros(3)
    )
    t0 = time.perf_counter()
    np.linalg.lstsq(np.column_stack([np.ones(m.n), f]), rec.accel_raw, rcond=None)
    t_base = time.perf_counter() - t0
    spec = ModelSpec(TERMS)
    t0 = time.perf_counter()
    fit = fit_dynamic_batch(m, rec.accel_raw, run.g_local_m_s2, np.zeros(3), spec)
    t_batch = time.perf_counter() - t0
    b0, K0 = linear_start(m, rec.accel_raw, run.g_local_m_s2, np.zeros(3))
    t0 = time.perf_counter()
    kr = run_dynamic_kalman(
        m,
        rec.accel_raw,
        run.g_local_m_s2,
        np.zeros(3),
        spec,
        initial_theta(spec, b0, K0, np.zeros(3)),
        fit.noise_sigma,
        smooth=True,
    )
    t_kf = time.perf_counter() - t0
    z = np.max(np.abs(kr.final.x - fit.theta) / fit.sigma)
    r_err_mm = 1e3 * np.max(np.abs(fit.theta[spec.index("lever_arm")] - [0.05, -0.02, 0.03]))
    print(f"{label}: {m.n} samples, {fit.n_used} used, {fit.iterations} Gauss-Newton iterations")
    print(f"  baseline lstsq [1 f]          {t_base:8.3f} s   1.0x")
    for name, t in (
        ("motion regressors", t_prep),
        ("batch fit + sandwich", t_batch),
        ("Kalman filter + RTS smoother", t_kf),
    ):
        print(f"  {name:29s} {t:8.3f} s   {t / t_base:.0f}x baseline")
    print(
        f"  filter vs batch max |z| {z:.3f}; lever arm error {r_err_mm:.2f} mm "
        f"(sigma {1e3 * fit.sigma[spec.index('lever_arm')].max():.2f} mm)"
    )


def main() -> None:
    for case in CASES:
        _case(*case)


if __name__ == "__main__":
    main()
