"""Planned designs fitted by the every-sample fit: predicted against achieved, and the bound.

The planner's ``"every-sample"`` family (``bench.planning.every_sample``): the planned-static
tumble (twelve icosahedron directions, antipodal order, short dwells, many passes) fitted by
the dynamic batch fit of every sample, moves and settling included. For each unit and table time
1.5…40 min, ``best_within(..., fit="every-sample")`` picks the design and predicts its RMS σ(K);
the design is then run

- on calbench's simulator (``drivers.sim``, trapezoidal moves at 200°/s and 200°/s², the limits
  the plan is made for) and fitted by ``calibrate_dynamic`` (bias and K), and
- on an independent simulator (``benchmarks.planning_independent_sim``): its own kinematics
  (quintic minimum-jerk moves of the same duration, orientations composed by
  ``scipy.spatial.transform.Rotation``, the angular rate and acceleration of the axis chain
  worked out from the profile's derivatives), its own noise (exact AR(1) Gauss-Markov, white,
  random walk) and its own least squares of every sample.

Each row prints the predicted RMS σ(K_ij), the achieved RMS K error of both simulators (over the
nine elements and the seeds), achieved / predicted, achieved / the white-noise bound of any
motion and the z spread (error / predicted σ per element). Then the time target: static-12 with
a 192 s dwell (40 min) under the window fit sets the U; ``plan(..., fits=("window",
"every-sample"))`` designs the shortest procedure for it, which is run on calbench's simulator.

``--effects``: every simulated unit has a base tilt of 3′ rms and a lever arm of a few cm: on
calbench's simulator (``study_planning.simulate_k_errors``) r = (3, −2, 1) cm, fitted with the
lever arm and the table tilt declared (``calibrate_dynamic(terms=("lever_arm", "table_tilt"))``);
on the independent one 3 cm in a random direction per seed, fitted by its own least squares with
r and the tilt as parameters. The prediction carries both as nuisance parameters
(``bench.planning.trajectory.nuisance_response``); each row also prints the prediction without
them.

Run: ``nice .venv/bin/python -m benchmarks.study_planning_dynamic [n_seeds] [--quick] [--effects]``
(``--quick``: 1.5, 6 and 24 min only, no static-12 reference); docs/planning.md quotes it.
"""

from __future__ import annotations

import sys

import numpy as np

from bench.planning.evaluation import Evaluation, Targets, evaluate
from bench.planning.noise import UnitNoise
from bench.planning.search import best_within, plan
from bench.procedures import build_procedure
from bench.procedures.preview import TableLimits
from benchmarks.planning_independent_sim import k_error
from benchmarks.study_planning import FS_HZ, G0, LENGTHS_MIN, achieved, simulate_k_errors

SIM_LIMITS = TableLimits(
    pos_lo_deg=(-180.0, -180.0, -180.0),
    pos_hi_deg=(180.0, 180.0, 180.0),
    max_rate_deg_s=(200.0, 200.0, 200.0),
    max_acc_deg_s2=(200.0, 200.0, 200.0),
    continuous=(True, False, True),
)
"""The limits calbench's simulator moves at in ``study_planning`` (200°/s, 200°/s²)."""

UNITS = {
    "ADXL325-like": UnitNoise.from_ug(250.0, 40.0, 200.0),
    "navigation-grade": UnitNoise.from_ug(20.0, 1.0, 100.0),
    "ADXL325-like + random walk 1 ug/rts": UnitNoise(
        250e-6 * G0, 40e-6 * G0, 200.0, random_walk_m_s2_rt_s=1e-6 * G0
    ),
}


def independent(
    e: Evaluation, noise: UnitNoise, n_seeds: int, base: int, effects: bool = False
) -> tuple[float, float]:
    """(RMS K error, z spread against ``e``'s prediction) on the independent simulator
    (``benchmarks.planning_independent_sim``; ``effects``: a tilted base and a lever arm, fitted)."""
    errs = np.array([k_error(e.procedure, noise, base + s, FS_HZ, effects) for s in range(n_seeds)])
    z = errs / e.predicted.k_elements[None]
    return float(np.sqrt(np.mean(errs**2))), float(np.std(z))


def rows(name: str, noise: UnitNoise, n_seeds: int, lengths: tuple[float, ...]) -> None:
    print(f"== {name}: {noise.describe()}; every-sample fit; {n_seeds} seeds")
    print("length  design            pred   calbench  ach/pred  ach/bound  z     indep  ach/pred  z")
    for i, minutes in enumerate(lengths):
        e = best_within(noise, minutes * 60, limits=SIM_LIMITS, fit="every-sample")
        err, z = achieved(e, noise, n_seeds, False, 300 + 50 * i, every_sample=True)
        ierr, iz = independent(e, noise, n_seeds, 300 + 50 * i)
        par = e.procedure.parameters
        p = e.predicted.k_rms
        print(
            f"{minutes:5.1f}  {par['dwell_s']:4.1f} s x{par['repeats']:>3}  {1e6 * p:7.2f}  "
            f"{1e6 * err:8.2f}  {err / p:8.2f}  {err / e.bound_k:9.2f}  {z:4.2f}  "
            f"{1e6 * ierr:6.2f}  {ierr / p:8.2f}  {iz:4.2f}",
            flush=True,
        )


def time_target(name: str, noise: UnitNoise, n_seeds: int) -> None:
    s12 = evaluate(build_procedure("static-12", dwell_s=192.0), noise, limits=SIM_LIMITS)
    errs = np.array([simulate_k_errors(s12.procedure, noise, s, False) for s in range(n_seeds)])
    err12 = float(np.sqrt(np.mean(errs**2)))
    r = err12 / s12.predicted.k_rms
    targets = Targets(scale=2 * r * s12.predicted.scale, misalignment_rad=2 * r * s12.predicted.misalignment)
    p = plan(
        noise, targets, limits=SIM_LIMITS, max_duration_s=s12.duration_s, fits=("window", "every-sample")
    )
    print(
        f"{name}: static-12 (192 s dwell, window fit) {s12.duration_s / 60:.1f} min, "
        f"achieved {1e6 * err12:.2f} ppm"
    )
    if p.best is None:
        print(f"  plan: none; {p.problems[0]}")
        return
    b = p.best
    errp, zp = achieved(b, noise, n_seeds, False, 100, every_sample=b.fit == "every-sample")
    print(
        f"  plan ({b.fit} fit) {b.procedure.parameters}: {b.duration_s / 60:.1f} min = "
        f"{b.duration_s / s12.duration_s:.0%} of static-12; predicted {1e6 * b.predicted.k_rms:.2f}, "
        f"achieved {1e6 * errp:.2f} ppm (z spread {zp:.2f})",
        flush=True,
    )


def nuisance_rows(name: str, noise: UnitNoise, n_seeds: int, lengths: tuple[float, ...]) -> None:
    """Rows with a tilted base and a lever arm (module docstring, ``--effects``)."""
    print(f"== {name}: {noise.describe()}; 3 arcmin tilt + 3 cm lever arm, fitted as terms; {n_seeds} seeds")
    print(
        "length  design           pred  pred w/o nuisance  calbench  ach/pred  ach/bound  z"
        "     indep  ach/pred  ach/bound  z"
    )
    for i, minutes in enumerate(lengths):
        e = best_within(noise, minutes * 60, limits=SIM_LIMITS, fit="every-sample")
        bare = evaluate(e.procedure, noise, limits=SIM_LIMITS, fit="every-sample", with_tilt=False)
        err, z = achieved(e, noise, n_seeds, True, 700 + 50 * i, every_sample=True)
        ierr, iz = independent(e, noise, n_seeds, 700 + 50 * i, effects=True)
        par = e.procedure.parameters
        p = e.predicted.k_rms
        print(
            f"{minutes:5.1f}  {par['dwell_s']:4.1f} s x{par['repeats']:>3}  {1e6 * p:7.2f}  "
            f"{1e6 * bare.predicted.k_rms:14.2f}"
            f"  {1e6 * err:8.2f}  {err / p:8.2f}  {err / e.bound_k:9.2f}  {z:4.2f}"
            f"  {1e6 * ierr:6.2f}  {ierr / p:8.2f}  {ierr / e.bound_k:9.2f}  {iz:4.2f}"
            + ("" if not e.notes else f"  ({e.notes[0]})"),
            flush=True,
        )


def independent_rows(name: str, noise: UnitNoise, n_seeds: int, lengths: tuple[float, ...]) -> None:
    """The independent simulator's columns of :func:`nuisance_rows` alone: the same designs and
    seeds (row i of :data:`LENGTHS_MIN` takes seeds 700 + 50·i), calbench's simulator not run."""
    print(f"== {name}: {noise.describe()}; 3 arcmin tilt + 3 cm lever arm, fitted as terms; {n_seeds} seeds")
    print("length  design           pred     indep  ach/pred  ach/bound  z")
    for minutes in lengths:
        i = LENGTHS_MIN.index(minutes)
        e = best_within(noise, minutes * 60, limits=SIM_LIMITS, fit="every-sample")
        ierr, iz = independent(e, noise, n_seeds, 700 + 50 * i, effects=True)
        par = e.procedure.parameters
        p = e.predicted.k_rms
        print(
            f"{minutes:5.1f}  {par['dwell_s']:4.1f} s x{par['repeats']:>3}  {1e6 * p:7.2f}"
            f"  {1e6 * ierr:8.2f}  {ierr / p:8.2f}  {ierr / e.bound_k:9.2f}  {iz:4.2f}",
            flush=True,
        )


def main(n_seeds: int, quick: bool, effects: bool = False) -> None:
    lengths = (1.5, 6.0, 24.0) if quick else LENGTHS_MIN
    if effects:
        for name in ("ADXL325-like", "navigation-grade"):
            nuisance_rows(name, UNITS[name], n_seeds, lengths)
        return
    for name, noise in UNITS.items():
        rows(name, noise, n_seeds, lengths)
    if not quick:
        for name, noise in UNITS.items():
            time_target(name, noise, n_seeds)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    main(int(args[0]) if args else 3, "--quick" in sys.argv, "--effects" in sys.argv)
