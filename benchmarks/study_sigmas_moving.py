"""z-scores of the moving-table fit and of its certificate budget against the concealed truth.

Three kinds of moving recording, simulated by ``drivers/sim`` for the ADXL325-like unit of
``SensorTruth.typical`` (250 µg/√Hz white noise, a 40 µg / 200 s Gauss–Markov bias wander,
16-bit converter) and fitted by the every-sample dynamic batch fit with bias and K
(``calibrate_dynamic``, terms declared empty):

- ``rate``: the bench's rate-1axis procedure (``bench.procedures.rate``: six poses × six rates,
  a 10 s dwell per rate window, about 12 minutes, 100 Hz);
- ``oscillation``: the two-axis oscillation, 600 s (10.5 minutes, 100 Hz);
- ``tumble``: the planner's every-sample design for 3 minutes of table time
  (``best_within(..., fit="every-sample")``: the planned-static tumble, moves included, 50 Hz);
- ``tumble-independent``: the same design on the independent simulator of
  ``benchmarks.planning_independent_sim`` (its own kinematics, quintic moves, exact AR(1)
  wander; a unit with K = I + 2e-3 N(0, 1), m/s² output; case ``clean`` only: that simulator
  has no temperature or pose errors).

Cases: ``clean``; ``realistic``: a zero-g temperature coefficient of 0.2 mg/°C (1 σ per
channel, seeded) under the simulator's default lab course (2 °C self-heating over 10 min,
±0.3 °C over 30 min) and a pose error of 1 arc-minute (1 σ per tilt angle) per pose of the
rate table and per window of the tumble (none on the oscillation: its one moving window would
make it a mount rotation, a different K). The bias truth is the bias at the run's mean
temperature.

Per seed: z of K (9) against the truth; z of the bias (3) against the run's mean bias (truth
+ K · the wander's mean over the fitted samples) and against the unit's long-run bias; each
with the fit's sigma (and against the run's mean with ``DynamicFit.bias_sigma_run_mean``,
``bias_run_own``); with the budget's bias lines that need no refit, the fit's sigma against
the run's mean and the unit's wander over the run (``bias_*_core``); and, with ``--budget``,
with the certificate budget's u_c (``bench.uncertainty.dynamic``, the station's default
Type B settings and its stated unit wander 40 µg / 200 s; 37 refits per seed).
Reported: RMS z per group (its spread), largest |z|, median over seeds of the worst |z| of the
12 parameters, and the share of fits whose ``bias_reference`` is ``"long_run"``.

    python -m benchmarks.study_sigmas_moving KIND CASE SEEDS [--budget] [--first=N]
"""

from __future__ import annotations

import math
import sys
from functools import cache

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration.dynamic import calibrate_dynamic
from bench.planning.noise import UnitNoise
from bench.planning.search import best_within
from bench.procedures.rate import DEFAULT_POSES_DEG, DEFAULT_RATES_DEG_S
from bench.procedures.steps import MoveTo, Procedure
from bench.recording import Recording
from bench.uncertainty.dynamic import dynamic_budget, dynamic_inputs
from bench.uncertainty.wander import wander_inputs
from benchmarks.planning_independent_sim import Motion, noise_series, quintic_state
from benchmarks.study_planning_dynamic import SIM_LIMITS
from drivers.sim.offline import (
    DEFAULT_AXES,
    SimulatedRun,
    simulate_oscillation,
    simulate_rate_steps,
    simulate_static,
)
from drivers.sim.physics import REFERENCE_TEMP_C, SensorPhysics
from drivers.sim.sensor_truth import G0_M_S2, SensorTruth

KINDS = ("rate", "oscillation", "tumble", "tumble-independent")
CASES = ("clean", "realistic")
TEMPCO_M_S2_PER_C = 0.2e-3 * G0_M_S2
POSE_RAD = math.radians(1.0 / 60.0)
RATE_DWELL_S = 10.0
OSCILLATION_S = 600.0
TUMBLE_S = 180.0
TUMBLE_FS_HZ = 50.0
TYPE_B = {
    "angle_u_rad": math.radians(0.001),
    "tilt_u_rad": 1e-5,
    "g_local_u_m_s2": 1e-5,
    "daq": (1e-5, 1e-5),
    "temp_coeff": (5e-4, 3e-5),
}
"""The station's default Type B settings (``station.settings.Settings``)."""
WANDER = (40e-6 * G0_M_S2, 200.0)
"""The unit's bias wander as the station states it (``bias_wander_m_s2``, ``bias_wander_corr_time_s``)."""


@cache
def tumble_procedure() -> Procedure:
    """The planner's every-sample design for ``TUMBLE_S`` of table time (ADXL325-like unit)."""
    noise = UnitNoise.from_ug(250.0, 40.0, 200.0)
    return best_within(noise, TUMBLE_S, limits=SIM_LIMITS, fit="every-sample").procedure


def pose_errors_rad(kind: str, rng: np.random.Generator) -> np.ndarray | None:
    """(windows, 2) the tilt error of each window: one draw per pose of the rate table (the
    middle and inner axes hold it through the pose's six rate windows), one per window of the
    tumble (the table reaches each pose anew); ``None`` for the oscillation, whose one moving
    window would make a pose error a constant mount rotation, i.e. a different K."""
    if kind == "rate":
        per_pose = POSE_RAD * rng.standard_normal((len(DEFAULT_POSES_DEG), 2))
        return np.repeat(per_pose, len(DEFAULT_RATES_DEG_S), axis=0)
    if kind == "tumble":
        n = sum(isinstance(s, MoveTo) for s in tumble_procedure().steps)
        return POSE_RAD * rng.standard_normal((n, 2))
    return None


def truth_for(kind: str, case: str, seed: int) -> SensorTruth:
    """The unit of one seed with the case's effects."""
    if case not in CASES:
        raise ValueError(f"case must be one of {CASES}, got {case!r}")
    tr = SensorTruth.typical("V", seed=seed)
    if case == "clean":
        return tr
    rng = np.random.default_rng([seed, 0x3A])
    effects: dict[str, dict[str, object]] = {
        "temperature_bias": {"tc_m_s2_per_c": TEMPCO_M_S2_PER_C * rng.standard_normal(3)}
    }
    pose = pose_errors_rad(kind, rng)
    if pose is not None:
        effects["pose_error"] = {"angles_rad": pose}
    return tr.with_effects(effects)


def simulate_independent(seed: int) -> SimulatedRun:
    """The planned tumble on the independent simulator (module docstring), packaged as a run:
    encoders are the commanded angles, the temperature constant, the wander kept apart."""
    proc, fs = tumble_procedure(), TUMBLE_FS_HZ
    motion = Motion(proc, fs)
    ang, _, _ = quintic_state(proc, fs)
    n = len(ang)
    rng = np.random.default_rng([seed, 0x1D])
    K = np.eye(3) + 2e-3 * rng.standard_normal((3, 3))
    b = 0.05 * rng.standard_normal(3)
    white = noise_series(UnitNoise(250e-6 * G0_M_S2, 0.0, 200.0), n, fs, rng)
    wander = noise_series(UnitNoise(1e-30, WANDER[0], WANDER[1]), n, fs, rng)
    y = b + (motion.force(np.zeros(3), np.zeros(2)) + wander + white) @ K.T
    truth = SensorTruth(bias=b, K=K, channel_unit="m/s2", noise=SensorTruth.typical("m/s2").noise)
    return SimulatedRun(
        t_s=np.arange(n) / fs,
        raw=y,
        encoder_deg=(ang + 180.0) % 360.0 - 180.0,
        temp_c=np.full(n, 25.0),
        segments=(),
        truth=truth,
        procedure="planned-static",
        sample_rate_hz=fs,
        axis_vectors=DEFAULT_AXES,
        mount=np.eye(3),
        g_local_m_s2=G0_M_S2,
        profile=None,  # type: ignore[arg-type]  # the fit reads the encoders, not the profile
        bias_wander_m_s2=wander,
    )


def simulate(kind: str, case: str, seed: int) -> SimulatedRun:
    """One recording of the study's unit (module docstring)."""
    if kind == "tumble-independent":
        if case != "clean":
            raise ValueError("the independent simulator has the clean case only")
        return simulate_independent(seed)
    ph = SensorPhysics(truth_for(kind, case, seed), DEFAULT_AXES, seed=3000 + seed)
    if kind == "rate":
        return simulate_rate_steps(
            ph, 100.0, rates_deg_s=DEFAULT_RATES_DEG_S, poses_deg=DEFAULT_POSES_DEG, dwell_s=RATE_DWELL_S
        )
    if kind == "oscillation":
        return simulate_oscillation(ph, 100.0, duration_s=OSCILLATION_S)
    if kind == "tumble":
        proc = tumble_procedure()
        poses = np.array([s.angles_deg for s in proc.steps if isinstance(s, MoveTo)])
        settle = float(proc.parameters["settle_s"])  # type: ignore[arg-type]
        dwell = float(proc.parameters["dwell_s"])  # type: ignore[arg-type]
        return simulate_static(
            poses, dwell, ph, TUMBLE_FS_HZ, move_rate_deg_s=200.0, move_accel_deg_s2=200.0, lead_s=settle
        )
    raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")


def truths(run: SimulatedRun) -> tuple[np.ndarray, np.ndarray]:
    """(run's mean bias, long-run bias), each (3,) channel units, at the run's mean temperature:
    the every-sample fit weighs all samples alike, so the run's mean is over all of them."""
    tr = run.truth
    long_run = np.array(tr.bias, dtype=float)
    fx = tr.effect_arrays().get("temperature_bias")
    if fx is not None:
        long_run = long_run + np.diag(tr.K) * fx["tc_m_s2_per_c"] * (
            float(np.mean(run.temp_c)) - REFERENCE_TEMP_C
        )
    return long_run + tr.K @ run.bias_wander_m_s2.mean(axis=0), long_run


def budget_u(
    rec: Recording, bias: np.ndarray, K: np.ndarray, sigma: np.ndarray, bias_sigma_run_mean: np.ndarray
) -> np.ndarray:
    """(12,) the certificate budget's u_c of [b, vec K] (``bench.uncertainty.dynamic``)."""
    inputs, _ = dynamic_inputs(rec, (), bias, K, **TYPE_B)  # type: ignore[arg-type]
    budget = dynamic_budget(
        rec, (), bias, K, np.diag(sigma**2), inputs, wander=WANDER, bias_sigma_run_mean=bias_sigma_run_mean
    )
    return np.array([q.u_c for q in budget.quantities])


def z_scores(kind: str, case: str, seed: int, with_budget: bool = False) -> dict[str, np.ndarray]:
    """z of K (9) and of the bias against the run's mean and the long-run bias (3 each), with the
    fit's sigma and (``with_budget``) the budget's u_c."""
    run = simulate(kind, case, seed)
    rec = to_recording(run, serial="SN-STUDY")
    res = calibrate_dynamic(rec, terms=(), cross_check=False)
    assert res.fit is not None
    run_mean, long_run = truths(run)
    dk = (res.K - run.truth.K).ravel()
    out = {
        "K": dk / res.K_sigma.ravel(),
        "bias_run": (res.bias - run_mean) / res.bias_sigma,
        "bias_long": (res.bias - long_run) / res.bias_sigma,
        "bias_run_own": (res.bias - run_mean) / res.fit.bias_sigma_run_mean,
        "long_run": np.array([float(res.bias_reference == "long_run")]),
        "minutes": np.array([run.t_s[-1] / 60.0]),
        "bias_sigma_ug": res.bias_sigma / np.diag(run.truth.K) / G0_M_S2 * 1e6,
    }
    _, w_sens = wander_inputs(float(rec.t_s[-1] - rec.t_s[0]), res.K, WANDER)
    u_core = np.sqrt(res.fit.bias_sigma_run_mean**2 + np.sum((w_sens[:, :3] * WANDER[0]) ** 2, axis=0))
    out["bias_run_core"] = (res.bias - run_mean) / u_core
    out["bias_long_core"] = (res.bias - long_run) / u_core
    if with_budget:
        sigma = np.concatenate([res.bias_sigma, res.K_sigma.ravel()])
        u = budget_u(rec, res.bias, res.K, sigma, res.fit.bias_sigma_run_mean)
        out["K_budget"] = dk / u[3:]
        out["bias_run_budget"] = (res.bias - run_mean) / u[:3]
        out["bias_long_budget"] = (res.bias - long_run) / u[:3]
    return out


def summary(out: list[dict[str, np.ndarray]]) -> dict[str, float]:
    """RMS z and largest |z| per group; median worst |z| of the 12 (K and the long-run bias)."""
    res: dict[str, float] = {"seeds": len(out), "minutes": float(out[0]["minutes"][0])}
    for k in out[0]:
        if not (k.startswith("K") or k.startswith("bias_")) or k == "bias_sigma_ug":
            continue
        z = np.concatenate([o[k] for o in out])
        res[f"rms_{k}"] = float(np.sqrt(np.mean(z**2)))
        res[f"max_{k}"] = float(np.max(np.abs(z)))
    res["median_worst12"] = float(np.median([np.max(np.abs(np.r_[o["K"], o["bias_long"]])) for o in out]))
    res["median_worst12_core"] = float(
        np.median([np.max(np.abs(np.r_[o["K"], o["bias_long_core"]])) for o in out])
    )
    res["share_long_run"] = float(np.mean([o["long_run"][0] for o in out]))
    labelled = [o["bias_long"] for o in out if o["long_run"][0]]
    if labelled:
        res["rms_bias_long_where_long_run"] = float(np.sqrt(np.mean(np.concatenate(labelled) ** 2)))
    s = np.array([o["bias_sigma_ug"] for o in out])
    res["bias_sigma_ug_median"] = float(np.median(s))
    res["bias_sigma_ug_p10_p90_ratio"] = float(np.percentile(s, 90) / np.percentile(s, 10))
    return res


def study(kind: str, case: str, seeds: int, with_budget: bool = False, first: int = 0) -> dict[str, float]:
    return summary([z_scores(kind, case, first + s, with_budget) for s in range(seeds)])


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    first = next((int(a.split("=")[1]) for a in sys.argv if a.startswith("--first=")), 0)
    r = study(args[0], args[1], int(args[2]), "--budget" in sys.argv, first)
    print(args[0], args[1], {k: round(v, 3) for k, v in r.items()}, flush=True)
