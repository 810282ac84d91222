"""K and bias z-scores of the static-12 window fit against pose order, duration, wander and
what real benches add.

The bench's static-12 poses (``bench.procedures.static``) in their execution order (antipodes
one after the other) or in the icosahedron's ring order (+z first, −z last, the former order),
simulated by ``drivers/sim`` for ``SensorTruth.typical`` (250 µg/√Hz, 40 µg / 200 s wander,
optionally a bias random walk) and fitted by ``calibrate_recording`` (window means, known
orientations). Cases (``CASES``), each adding to the clean unit:

- ``clean``: nothing;
- ``temperature``: a zero-g temperature coefficient of 0.2 mg/°C (1 σ per channel, seeded)
  under the default lab course (2 °C self-heating over 10 min, ±0.3 °C over 30 min);
- ``pose``: each pose placed with a random error of 3 arc-minutes (1 σ per tilt angle);
- ``motion``: half the windows nudged: a tilt step of 3 arc-minutes (1 σ per angle) at a
  random time inside the window, kept to the end of the window;
- ``all``: the three together.

The bias truth of the temperature cases is the bias at the windows' mean temperature.

Per case: RMS of the K z-scores against the truth (9 per seed), of the bias against the
run's mean and the long-run bias (and against the long-run bias over the fits whose
``bias_reference`` is ``long_run`` alone), the largest |z| of K; and the bias with the
certificate budget's bias lines that need no Type B input (``_core``): the fit's sigma against
the run's mean (``bias_sigma_run_mean``) and the unit's stated wander (40 µg / 200 s, the
simulated unit's own) averaged over the windows' span (``bench.uncertainty.wander``), with the
largest |z| of the long-run bias and the p90/p10 ratio of the stated bias sigmas; and
(``_cert``) with the certificate budget's u_c of bias and K (``station.certificates.budget``)
with every Type B input at zero but the stated wander: its Type A line (the fit's estimator with
the excess estimated without bias, ``bench.uncertainty.type_a``) and the wander's lines
(``_cert_no_wander``: the same budget without the wander, as static budgets were before).

    python -m benchmarks.study_sigmas_static ORDER DWELL_S SEEDS [RANDOM_WALK] [CASE]

ORDER ``bench`` or ``ring``; the run lasts about 12 × (DWELL_S + 6) s; RANDOM_WALK in
m/s²/√s (0: none); CASE one of ``CASES`` (default ``clean``).
"""

from __future__ import annotations

import dataclasses
import math
import sys

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration import calibrate_recording
from bench.calibration.analysis import analyse
from bench.procedures.static import icosahedron_up_directions, pose_for_up, static_12_poses_deg
from bench.uncertainty.wander import wander_inputs
from drivers.sim.offline import DEFAULT_AXES, SimulatedRun, simulate_static
from drivers.sim.physics import REFERENCE_TEMP_C, SensorPhysics
from drivers.sim.sensor_truth import G0_M_S2, SensorTruth
from station.certificates.budget import TypeBSettings, certificate_budget

CASES = ("clean", "temperature", "pose", "motion", "all")
ARCMIN_RAD = math.radians(1.0 / 60.0)
TEMPCO_M_S2_PER_C = 0.2e-3 * G0_M_S2
POSE_RAD = 3.0 * ARCMIN_RAD
NUDGE_RAD = 3.0 * ARCMIN_RAD
WANDER = (40e-6 * G0_M_S2, 200.0)
"""The unit's bias wander as the station states it (``bias_wander_m_s2``, ``bias_wander_corr_time_s``)."""
WANDER_ONLY = TypeBSettings(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, *WANDER)
"""Certificate budget settings: no Type B input but the unit's stated wander."""
NO_INPUT = TypeBSettings(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
"""The same without the wander (the static budget before it had the wander's lines)."""


def poses(order: str) -> np.ndarray:
    """(12, 3) table angles (deg) in the order visited."""
    if order == "bench":
        return np.array(static_12_poses_deg())
    if order == "ring":
        outer = (0.0, 90.0, 180.0, -90.0)
        return np.array([pose_for_up(d, outer[i % 4]) for i, d in enumerate(icosahedron_up_directions())])
    raise ValueError(f"order must be 'bench' or 'ring', got {order!r}")


def truth_for(case: str, seed: int, random_walk: float) -> SensorTruth:
    """The unit of one seed with the case's effects."""
    tr = SensorTruth.typical("V", seed=seed)
    if random_walk:
        tr = dataclasses.replace(
            tr, noise=dataclasses.replace(tr.noise, random_walk_m_s2_s_rt_hz=random_walk)
        )
    rng = np.random.default_rng([seed, 0x5A])
    effects: dict[str, dict[str, object]] = {}
    if case in ("temperature", "all"):
        effects["temperature_bias"] = {"tc_m_s2_per_c": TEMPCO_M_S2_PER_C * rng.standard_normal(3)}
    if case in ("pose", "all"):
        effects["pose_error"] = {"angles_rad": POSE_RAD * rng.standard_normal((12, 2))}
    return tr.with_effects(effects) if effects else tr


def nudge(run: SimulatedRun, seed: int) -> SimulatedRun:
    """The run with half its windows nudged (module docstring): from a random time inside
    the window to its end, raw += K (δ × f), f the true specific force of the window."""
    rng = np.random.default_rng([seed, 0x6B])
    raw = run.raw.copy()
    K, b = run.truth.K, run.truth.bias
    for a, e, _ in run.segments:
        if rng.random() < 0.5:
            continue
        t0 = a + (e - a) * rng.random()
        inside = (run.t_s >= t0) & (run.t_s <= e)
        f = np.linalg.solve(K, (raw[inside] - b).mean(axis=0))
        delta = np.r_[NUDGE_RAD * rng.standard_normal(2), 0.0]
        raw[inside] += K @ np.cross(delta, f)
    return dataclasses.replace(run, raw=raw)


def temperature_offset(run: SimulatedRun) -> np.ndarray:
    """(3,) the temperature's mean share of the bias over the run's windows (channel units):
    the bias a calibration at this course of temperature sees, beside the wander."""
    fx = run.truth.effect_arrays().get("temperature_bias")
    if fx is None:
        return np.zeros(3)
    inside = np.zeros(run.t_s.shape, dtype=bool)
    for a, e, _ in run.segments:
        inside |= (run.t_s >= a) & (run.t_s <= e)
    dt_c = float(np.mean(run.temp_c[inside])) - REFERENCE_TEMP_C
    return np.asarray(np.diag(run.truth.K) * fx["tc_m_s2_per_c"] * dt_c, dtype=float)


def z_scores(
    order: str, dwell_s: float, seed: int, random_walk: float = 0.0, case: str = "clean"
) -> dict[str, np.ndarray]:
    """z of K (9), of the bias against the run's mean (3) and against the long-run bias (3)."""
    if case not in CASES:
        raise ValueError(f"case must be one of {CASES}, got {case!r}")
    tr = truth_for(case, seed, random_walk)
    run = simulate_static(poses(order), dwell_s, SensorPhysics(tr, DEFAULT_AXES, seed=2000 + seed), 100.0)
    if case in ("motion", "all"):
        run = nudge(run, seed)
    rec = to_recording(run, serial="SN-STUDY")
    res = calibrate_recording(rec)
    thermal = temperature_offset(run)
    analysis = analyse(rec)
    cert = certificate_budget(analysis, analysis.fitted_model(), WANDER_ONLY)
    u_cert = np.array([q.u_c for q in cert.budget.quantities])
    before = certificate_budget(analysis, analysis.fitted_model(), NO_INPUT)
    u_before = np.array([q.u_c for q in before.budget.quantities[:3]])
    assert res.bias_sigma_run_mean is not None
    span_s = max(w.end_s for w in res.windows) - min(w.start_s for w in res.windows)
    _, w_sens = wander_inputs(span_s, res.K, WANDER)
    u_core = np.sqrt(res.bias_sigma_run_mean**2 + np.sum((w_sens[:, :3] * WANDER[0]) ** 2, axis=0))
    return {
        "K_cert": ((res.K - tr.K).ravel() / u_cert[3:]),
        "bias_long_cert": (res.bias - tr.bias - thermal) / u_cert[:3],
        "bias_long_cert_no_wander": (res.bias - tr.bias - thermal) / u_before,
        "bias_run_core": (res.bias - run.bias_seen() - thermal) / u_core,
        "bias_long_core": (res.bias - tr.bias - thermal) / u_core,
        "sigma_fit": res.bias_sigma / np.diag(tr.K),
        "sigma_core": u_core / np.diag(tr.K),
        "K": ((res.K - tr.K) / res.K_sigma).ravel(),
        "bias_run": (res.bias - run.bias_seen() - thermal) / res.bias_sigma,
        "bias_long": (res.bias - tr.bias - thermal) / res.bias_sigma,
        "minutes": np.array([run.t_s[-1] / 60.0]),
        "long_run": np.array([float(res.bias_reference == "long_run")]),
    }


def study(
    order: str, dwell_s: float, seeds: int, random_walk: float = 0.0, case: str = "clean"
) -> dict[str, float]:
    """RMS z per group, the largest |z| of K and the share of fits whose bias is the long run's
    (``rms_z_bias_long_where_long_run``: the long-run bias z over those fits alone)."""
    out = [z_scores(order, dwell_s, s, random_walk, case) for s in range(seeds)]
    rms = {
        k: float(np.sqrt(np.mean(np.concatenate([o[k] for o in out]) ** 2)))
        for k in (
            "K",
            "bias_run",
            "bias_long",
            "bias_run_core",
            "bias_long_core",
            "K_cert",
            "bias_long_cert",
            "bias_long_cert_no_wander",
        )
    }
    spread = {
        f"sigma_p90_p10_{k}": float(np.percentile(s, 90) / np.percentile(s, 10))
        for k in ("sigma_fit", "sigma_core")
        for s in [np.concatenate([o[k] for o in out])]
    }
    labelled = [o["bias_long"] for o in out if o["long_run"][0]]
    return {
        "minutes": float(out[0]["minutes"][0]),
        **{f"rms_z_{k}": v for k, v in rms.items()},
        "rms_z_bias_long_where_long_run": (
            float(np.sqrt(np.mean(np.concatenate(labelled) ** 2))) if labelled else float("nan")
        ),
        "max_abs_z_K": float(max(np.max(np.abs(o["K"])) for o in out)),
        "max_abs_z_bias_long": float(max(np.max(np.abs(o["bias_long"])) for o in out)),
        "max_abs_z_bias_long_core": float(max(np.max(np.abs(o["bias_long_core"])) for o in out)),
        "max_abs_z_bias_long_cert": float(max(np.max(np.abs(o["bias_long_cert"])) for o in out)),
        **spread,
        "share_long_run": float(np.mean([o["long_run"][0] for o in out])),
    }


if __name__ == "__main__":
    o, d, n = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
    rw = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
    c = sys.argv[5] if len(sys.argv) > 5 else "clean"
    print(o, d, n, rw, c, {key: round(v, 3) for key, v in study(o, d, n, rw, c).items()})
