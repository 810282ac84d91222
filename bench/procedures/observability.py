"""Can a planned procedure determine the model's parameters? Checked before a run.

The procedure's steps are laid out as encoder angles (:func:`procedure_angles`), the dynamic
model is evaluated along them for a nominal sensor, and its Fisher information is judged as
in :mod:`bench.estimation.observability` (rank in correlation form, Cramér–Rao sigmas against
``USEFUL_SIGMA``).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from bench.estimation.dynamic_model import G0_M_S2, TERM_ORDER, ModelSpec, initial_theta
from bench.estimation.motion_data import prepare_motion
from bench.estimation.observability import (
    USEFUL_SIGMA,
    ObservabilityReport,
    fisher_information,
    information_report,
)
from bench.procedures.steps import Dwell, MoveTo, NoiseWindow, Oscillate, Procedure, Rotate

FloatArray = npt.NDArray[np.float64]


def _min_jerk(a: FloatArray, b: FloatArray, n: int) -> FloatArray:
    u = (np.arange(1, n + 1) / n)[:, None]
    return a + (b - a) * (10 * u**3 - 15 * u**4 + 6 * u**5)


def procedure_angles(
    proc: Procedure,
    sample_rate_hz: float = 50.0,
    *,
    dwell_s: float = 60.0,
    start_deg: tuple[float, ...] | None = None,
    move_rate_deg_s: float = 30.0,
    accel_deg_s2: float = 100.0,
) -> tuple[FloatArray, FloatArray]:
    """The planned encoder angles of a procedure, sampled: (t (n,) s, angles (n, k) rad, unwrapped).

    Moves are minimum-jerk profiles lasting the longest axis's distance / ``move_rate_deg_s``
    (at least 1 s) plus ``settle_s``; dwells and noise windows hold (``dwell_s`` when a
    dwell is not yet chosen); a rotation ramps at ``accel_deg_s2``, holds its rate for
    spin-up and window, and ramps down; an oscillation follows c + A·sin(2πt/T) per axis.
    """
    h = 1.0 / sample_rate_hz
    pos = np.zeros(proc.n_axes) if start_deg is None else np.asarray(start_deg, dtype=float)
    chunks: list[FloatArray] = [pos[None, :].copy()]

    def hold(dur: float) -> None:
        n = max(1, round(dur / h))
        chunks.append(np.repeat(chunks[-1][-1:], n, axis=0))

    for step in proc.steps:
        cur = chunks[-1][-1]
        if isinstance(step, MoveTo):
            target = np.asarray(step.angles_deg, dtype=float)
            d = (target - cur + 180.0) % 360.0 - 180.0
            dur = max(1.0, float(np.max(np.abs(d))) / move_rate_deg_s)
            chunks.append(_min_jerk(cur, cur + d, max(2, round(dur / h))))
            hold(step.settle_s)
        elif isinstance(step, NoiseWindow | Dwell):
            hold(dwell_s if step.duration_s is None else step.duration_s)
        elif isinstance(step, Rotate):
            ax, w = step.axis - 1, step.rate_deg_s
            t_r = abs(w) / accel_deg_s2
            t = np.arange(1, round((2 * t_r + step.spinup_s + step.duration_s) / h) + 1) * h
            total = t[-1] if t.size else 0.0
            rate = np.sign(w) * np.minimum.reduce(
                [accel_deg_s2 * t, np.full_like(t, abs(w)), accel_deg_s2 * np.maximum(total - t, 0.0)]
            )
            block = np.repeat(cur[None, :], t.shape[0], axis=0)
            block[:, ax] = cur[ax] + np.cumsum(rate) * h
            chunks.append(block)
        elif isinstance(step, Oscillate):
            t = np.arange(1, round(step.duration_s / h) + 1) * h
            block = np.repeat(cur[None, :], t.shape[0], axis=0)
            for a, amp, per in zip(step.axes, step.amplitudes_deg, step.periods_s, strict=True):
                block[:, a - 1] = cur[a - 1] + amp * np.sin(2.0 * np.pi * t / per)
            chunks.append(block)
    q = np.vstack(chunks)
    t_s = np.arange(q.shape[0], dtype=float) * h
    return t_s, np.asarray(np.deg2rad(q), dtype=float)


def plan_observability(
    proc: Procedure,
    terms: tuple[str, ...] = TERM_ORDER,
    *,
    axis_vectors: npt.ArrayLike = ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    noise_m_s2_rt_hz: float = 250e-6 * G0_M_S2,
    sample_rate_hz: float = 50.0,
    dwell_s: float = 60.0,
) -> tuple[ObservabilityReport, dict[str, str]]:
    """Check before a run that the procedure determines every parameter of the chosen terms.

    The model is evaluated for a nominal unit (K = I in m/s², zero bias, level table, the
    lever arm at the origin) with white noise ``noise_m_s2_rt_hz`` (default the ADXL325 data
    sheet's 250 µg/√Hz); the sample rate only sets the time step, the bound follows the
    noise density.

    :returns: the report and, per term, why it is not worth fitting (undetermined, or its
        Cramér–Rao sigma above ``USEFUL_SIGMA``); an empty dict means the plan is good.
    """
    t, q = procedure_angles(proc, sample_rate_hz, dwell_s=dwell_s)
    m = prepare_motion(t, q, axis_vectors, np.eye(3))
    spec = ModelSpec(terms)
    theta = initial_theta(spec, np.zeros(3), np.eye(3), np.zeros(3))
    sigma = np.full(3, noise_m_s2_rt_hz * np.sqrt(sample_rate_hz))
    rep = information_report(fisher_information(m, theta, spec, G0_M_S2, np.zeros(3), sigma), spec.names)
    why: dict[str, str] = {}
    for term in ("bias", "scale_matrix", *spec.terms):
        bad = [r for r in rep.unobservable if any(n in r for n in spec.names[spec.index(term)])]
        crb = float(np.max(rep.crb_sigma[spec.index(term)]))
        if bad:
            why[term] = "; ".join(bad)
        elif term in USEFUL_SIGMA and crb > USEFUL_SIGMA[term]:
            why[term] = f"Cramér–Rao sigma {crb:.3g} exceeds {USEFUL_SIGMA[term]:g}"
    return rep, why


def plan_blockers(proc: Procedure, dwell_s: float = 60.0) -> list[str]:
    """Problems that make a moving-table procedure useless for calibration, one sentence each.

    The minimal dynamic model (bias, K, lever arm) must be determined by the planned motion;
    weaker terms are only left out of the fit, so they are not problems. Evaluated at 25 Hz
    (the bound follows the noise density, not the rate).
    """
    _, why = plan_observability(proc, ("lever_arm",), sample_rate_hz=25.0, dwell_s=dwell_s)
    return [f"{proc.name}: the motion cannot determine {term} ({reason})" for term, reason in why.items()]
