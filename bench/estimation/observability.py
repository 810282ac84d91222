"""Which parameters a motion can determine: the Fisher information of the dynamic model.

For the measurement model raw = h(θ) + e with white noise of standard deviation σ_c per
channel, the Fisher information is F = Σ_t J_tᵀ diag(1/σ²) J_t and its inverse is the
Cramér–Rao bound on Cov(θ̂) (Kay, *Fundamentals of Statistical Signal Processing:
Estimation Theory*, §3.7). F is judged in correlation form, C = D⁻¹ F D⁻¹ with
D = sqrt(diag F), so that parameters in volts, metres and seconds compare: an eigenvalue
of C below ``RANK_TOL`` is a direction of θ the motion does not determine, and the
parameters with the largest components of its eigenvector are named. A parameter with
no information at all (a zero column) is named with the motion it would need.

The same information for a planned procedure, before a run, is
:func:`bench.procedures.observability.plan_observability`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.dynamic_model import ModelSpec, predict
from bench.estimation.motion_data import MotionData

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
        _, J = predict(
            theta, m.take(idx[a : a + chunk], rates=spec.needs_rates), spec, g_m_s2, lever, jacobian=True
        )
        assert J is not None
        Jw = (J * np.sqrt(w)[None, :, None]).reshape(-1, p)
        F += Jw.T @ Jw
    return F
