"""Which parameters a motion can determine: the Fisher information of the dynamic model.

For the measurement model raw = h(θ) + e with white noise of standard deviation σ_c per
channel, the Fisher information is F = Σ_t J_tᵀ diag(1/σ²) J_t and its inverse is the
Cramér–Rao bound on Cov(θ̂) (Kay, *Fundamentals of Statistical Signal Processing:
Estimation Theory*, §3.7). F is judged in correlation form, C = D⁻¹ F D⁻¹ with
D = sqrt(diag F), so that parameters in volts, metres and seconds compare: an eigenvalue
of C below ``RANK_TOL`` is a direction of θ the motion does not determine, and the
parameters with the largest components of its eigenvector are named. A parameter with
no information at all (a zero column) is named with the motion it would need.

:func:`plan_observability` evaluates F for a planned procedure before a run: it lays out
the procedure's steps as encoder angles (``procedure_angles``) and evaluates the model at
a nominal sensor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.dynamic_model import (
    G0_M_S2,
    TERM_ORDER,
    ModelSpec,
    MotionData,
    initial_theta,
    predict,
    prepare_motion,
)
from bench.procedures.steps import Dwell, MoveTo, NoiseWindow, Oscillate, Procedure, Rotate

FloatArray = npt.NDArray[np.float64]

USEFUL_SIGMA = {
    "lever_arm": 5e-3,
    "proof_mass_offsets": 1e-3,
    "nonlinearity_quadratic": 1e-3,
    "table_tilt": 1e-3,
    "time_skew": 2e-3,
}
"""Largest Cramér–Rao sigma at which a term is worth fitting (m, m, 1/g, rad, s)."""
RANK_TOL = 1e-9
"""Smallest eigenvalue of the correlation-form information accepted as 'determined'."""
_NEEDS = {
    "r": "rotation (centripetal ω²r or tangential ω̇r)",
    "q": "rotation with each sensor axis in the plane of rotation at several orientations",
    "k2": "specific force spanning ±g on that axis",
    "tilt": "the outer (vertical) axis turning, or motion that tilts gravity about the base axes",
    "delay": "a specific force that changes while samples are taken",
    "bias": "gravity turned through opposite directions",
    "K": "gravity turned through three dimensions",
}


@dataclass(frozen=True)
class ObservabilityReport:
    """Rank and conditioning of the information of one motion.

    :param names: parameter names.
    :param rank: numerical rank of the correlation-form information.
    :param condition: its condition number (largest / smallest eigenvalue).
    :param unobservable: human-readable reasons, one per undetermined direction.
    :param crb_sigma: (p,) Cramér–Rao one-sigma bound per parameter (inf if undetermined).
    """

    names: tuple[str, ...]
    rank: int
    condition: float
    unobservable: tuple[str, ...]
    crb_sigma: FloatArray

    @property
    def ok(self) -> bool:
        """Every parameter is determined."""
        return not self.unobservable


def _need(name: str) -> str:
    key = name.split("_")[0]
    return _NEEDS.get(key, "more varied motion")


def information_report(F: npt.ArrayLike, names: list[str] | tuple[str, ...]) -> ObservabilityReport:
    """Analyse a Fisher information matrix F (p, p) whose parameters are ``names``."""
    Fm = np.asarray(F, dtype=float)
    p = Fm.shape[0]
    d = np.sqrt(np.clip(np.diag(Fm), 0.0, None))
    zero = d <= 1e-300
    reasons = [f"{names[i]}: no information (needs {_need(names[i])})" for i in np.flatnonzero(zero)]
    keep = np.flatnonzero(~zero)
    crb = np.full(p, np.inf)
    C = Fm[np.ix_(keep, keep)] / np.outer(d[keep], d[keep])
    evals, evecs = np.linalg.eigh(C)
    bad = evals < RANK_TOL * max(float(evals[-1]), 1e-300)
    for k in np.flatnonzero(bad):
        v = evecs[:, k]
        big = np.argsort(-np.abs(v))
        involved = [names[keep[j]] for j in big if abs(v[j]) > 0.25 * np.abs(v).max()][:6]
        reasons.append(
            f"{' + '.join(involved)}: only a combination is determined, not each (needs {_need(involved[0])})"
        )
    rank = int(np.sum(~bad))
    cond = float(evals[-1] / evals[0]) if evals.size and evals[0] > 0 else np.inf
    if not bad.any() and keep.size:
        Cinv = np.linalg.inv(C)
        crb[keep] = np.sqrt(np.diag(Cinv)) / d[keep]
    return ObservabilityReport(tuple(names), rank, cond, tuple(reasons), crb)


def check_information(F: npt.ArrayLike, names: list[str] | tuple[str, ...]) -> ObservabilityReport:
    """:func:`information_report`, raising ``ValueError`` that names what cannot be determined."""
    rep = information_report(F, names)
    if not rep.ok:
        raise ValueError("the motion cannot determine every parameter: " + "; ".join(rep.unobservable))
    return rep


def fisher_information(
    m: MotionData,
    theta: FloatArray,
    spec: ModelSpec,
    g_m_s2: float,
    lever_arm_m: npt.ArrayLike,
    noise_sigma: npt.ArrayLike,
    *,
    chunk: int = 20_000,
) -> FloatArray:
    """F = Σ_t J_tᵀ diag(1/σ²) J_t of the dynamic model over the usable samples of ``m``, (p, p).

    :param noise_sigma: (3,) white-noise sigma per channel (channel units).
    """
    w = 1.0 / np.asarray(noise_sigma, dtype=float).reshape(3) ** 2
    lever = np.asarray(lever_arm_m, dtype=float).reshape(3)
    p = spec.n_params
    F = np.zeros((p, p))
    idx = np.flatnonzero(m.valid)
    for a in range(0, idx.shape[0], chunk):
        _, J = predict(theta, m.take(idx[a : a + chunk]), spec, g_m_s2, lever, jacobian=True)
        assert J is not None
        Jw = (J * np.sqrt(w)[None, :, None]).reshape(-1, p)
        F += Jw.T @ Jw
    return F


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
