"""The planner against the simulator: predicted U, achieved error, table time, the bound.

For an ADXL325-like unit (250 µg/√Hz white, 40 µg Gauss-Markov wander with 200 s correlation)
and a navigation-grade unit (20 µg/√Hz white, 1 µg wander, 100 s), on calbench's simulator
(drivers/sim, the same physics as ``calbench simulate``) and the static window fit
(``calibrate_recording``):

1. static-12 with a 192 s dwell (40 min): its predicted U per group (scale, misalignment),
   scaled by its achieved / predicted RMS K error over the seeds, is the target; ``plan``
   designs the planned-static procedure for it and the planned design is simulated: its table
   time over 40 min, achieved error, predicted σ.
2. at table times 1.5, 3, 6, 12, 24, 40 min the planner's best design in that time
   (``best_within``): predicted RMS σ(K), achieved RMS error, achieved / predicted, achieved /
   the white-noise bound of any motion, and the z spread (error / predicted σ per element).

``--effects`` adds a base tilt of 3′ and a lever arm of 3 cm to every simulated unit;
``--every-sample`` fits the same designs with the dynamic batch fit of every sample instead.

Run: ``nice .venv/bin/python -m benchmarks.study_planning [n_seeds] [--effects]``;
docs/benchmarks.md and docs/planning.md quote its output.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration import calibrate_recording
from bench.calibration.dynamic import calibrate_dynamic
from bench.planning.evaluation import Evaluation, Targets, evaluate
from bench.planning.noise import UnitNoise
from bench.planning.search import best_within, plan
from bench.procedures import build_procedure, preview
from bench.procedures.steps import MoveTo, Procedure
from bench.recording import Recording
from drivers.sim.noise import NoiseSpec
from drivers.sim.offline import DEFAULT_AXES, simulate_static
from drivers.sim.physics import SensorPhysics, SensorTruth

G0 = 9.80665
ARCMIN = math.pi / 180 / 60
FS_HZ = 50.0
LENGTHS_MIN = (1.5, 3.0, 6.0, 12.0, 24.0, 40.0)
UNITS = {
    "ADXL325-like": UnitNoise.from_ug(250.0, 40.0, 200.0),
    "navigation-grade": UnitNoise.from_ug(20.0, 1.0, 100.0),
}


def simulate_recording(
    proc: Procedure, noise: UnitNoise, seed: int, effects: bool
) -> tuple[Recording, SensorTruth]:
    """One simulated run of ``proc`` on calbench's simulator (trapezoidal moves at 200°/s and
    200°/s², ``FS_HZ``) for a typical unit of seed ``seed`` with ``noise``, and with ``effects``
    a base tilt (3′ rms) and a lever arm r = (3, −2, 1) cm; returns the recording and the truth."""
    typ = SensorTruth.typical("m/s2", seed=seed)
    spec = NoiseSpec(
        white_m_s2_rt_hz=noise.white_m_s2_rt_hz,
        bias_instability_m_s2=noise.wander_m_s2,
        bias_instability_tau_s=noise.wander_tau_s,
        random_walk_m_s2_s_rt_hz=noise.random_walk_m_s2_rt_s,
    )
    truth = typ.with_noise(spec)
    if effects:
        rng = np.random.default_rng([seed, 23])
        tilt = 3 * ARCMIN * rng.standard_normal(2) / math.sqrt(2)
        truth = truth.with_effects(
            {"table_tilt": {"tilt_rad": tuple(tilt)}, "lever_arm": {"r_m": (0.03, -0.02, 0.01)}}
        )
    ph = SensorPhysics(truth, DEFAULT_AXES, seed=5000 + seed)
    poses = np.array([s.angles_deg for s in proc.steps if isinstance(s, MoveTo)])
    settle = float(proc.parameters["settle_s"])  # type: ignore[arg-type]
    dwell = float(proc.parameters["dwell_s"])  # type: ignore[arg-type]
    run = simulate_static(
        poses, dwell, ph, FS_HZ, move_rate_deg_s=200.0, move_accel_deg_s2=200.0, lead_s=settle
    )
    return to_recording(run, serial="SN-PLAN"), truth


def simulate_k_errors(
    proc: Procedure, noise: UnitNoise, seed: int, effects: bool, every_sample: bool = False
) -> np.ndarray:
    """(3, 3) K error of the window fit (``every_sample``: the dynamic batch fit of every sample,
    moves included, bias and K only, and with ``effects`` the lever arm and the table tilt
    declared beside them) on one simulated run of ``proc`` (:func:`simulate_recording`;
    dimensionless)."""
    rec, truth = simulate_recording(proc, noise, seed, effects)
    if every_sample:
        dyn = calibrate_dynamic(rec, terms=("lever_arm", "table_tilt") if effects else (), cross_check=False)
        return np.asarray(dyn.K - truth.K, dtype=float)
    res = calibrate_recording(rec)
    return np.asarray(res.K - truth.K, dtype=float)


def achieved(
    e: Evaluation, noise: UnitNoise, n_seeds: int, effects: bool, base: int, every_sample: bool = False
) -> tuple[float, float]:
    """(RMS K error over elements and seeds, z spread against the window fit's prediction) of ``e``'s
    procedure."""
    errs = np.array(
        [simulate_k_errors(e.procedure, noise, base + s, effects, every_sample) for s in range(n_seeds)]
    )
    z = errs / e.predicted.k_elements[None]
    return float(np.sqrt(np.mean(errs**2))), float(np.std(z))


def main(n_seeds: int = 3, effects: bool = False) -> None:
    for name, noise in UNITS.items():
        print(
            f"== {name}: {noise.describe()}; {n_seeds} seeds; "
            f"effects {'tilt 3 arcmin + lever arm' if effects else 'none'}"
        )
        s12 = evaluate(build_procedure("static-12", dwell_s=192.0), noise)
        err12, z12 = achieved(s12, noise, n_seeds, effects, 0)
        print(
            f"static-12 192 s dwell: {s12.duration_s / 60:.1f} min, "
            f"predicted {1e6 * s12.predicted.k_rms:.2f} ppm, "
            f"achieved {1e6 * err12:.2f} ppm (z spread {z12:.2f}), bound {1e6 * s12.bound_k:.2f} ppm"
        )
        r = err12 / s12.predicted.k_rms  # static-12's per-group U, scaled to what it achieved
        targets = Targets(
            scale=2 * r * s12.predicted.scale, misalignment_rad=2 * r * s12.predicted.misalignment
        )
        p = plan(noise, targets, max_duration_s=s12.duration_s)
        if p.best is None:
            print(f"plan for {1e6 * err12:.2f} ppm (k=1): none; {p.problems[0]}")
        else:
            b = p.best
            errp, zp = achieved(b, noise, n_seeds, effects, 100)
            print(
                f"plan for {1e6 * err12:.2f} ppm: {b.procedure.parameters} {b.duration_s / 60:.1f} min = "
                f"{b.duration_s / s12.duration_s:.0%} of static-12; predicted {1e6 * b.predicted.k_rms:.2f}, "
                f"achieved {1e6 * errp:.2f} ppm (z spread {zp:.2f})"
            )
        print("length  design                     pred    achieved  ach/pred  ach/bound  z-spread")
        for i, minutes in enumerate(LENGTHS_MIN):
            e = best_within(noise, minutes * 60)
            err, z = achieved(e, noise, n_seeds, effects, 200 + 50 * i)
            par = e.procedure.parameters
            assert preview(e.procedure).duration_s <= minutes * 60 + 1e-6
            print(
                f"{minutes:5.1f}  dwell {par['dwell_s']:5.1f} s x{par['repeats']:>3}   "
                f"{1e6 * e.predicted.k_rms:7.2f}  {1e6 * err:8.2f}  {err / e.predicted.k_rms:8.2f}  "
                f"{err / e.bound_k:9.2f}  {z:8.2f}",
                flush=True,
            )


def every_sample(n_seeds: int, lengths_min: tuple[float, ...] = LENGTHS_MIN) -> None:
    """The same planned designs fitted by the dynamic batch fit of every sample (moves included):
    what the table time spent moving is worth; the planner does not predict this fit."""
    for name, noise in UNITS.items():
        print(f"== {name}, every-sample fit; {n_seeds} seeds")
        print("length  design                 window-fit pred  achieved  ach/bound")
        for i, minutes in enumerate(lengths_min):
            e = best_within(noise, minutes * 60)
            err, _ = achieved(e, noise, n_seeds, False, 200 + 50 * i, every_sample=True)
            par = e.procedure.parameters
            print(
                f"{minutes:5.1f}  dwell {par['dwell_s']:5.1f} s x{par['repeats']:>3}   "
                f"{1e6 * e.predicted.k_rms:10.2f}  {1e6 * err:8.2f}  {err / e.bound_k:9.2f}",
                flush=True,
            )


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if "--every-sample" in sys.argv:
        every_sample(int(args[0]) if args else 3)
    else:
        main(int(args[0]) if args else 3, "--effects" in sys.argv)
