"""Head to head of the bench families against the catalogue's claims on a moving recording.

An angle-locked disturbance or a delay that grows along the run can be taken by catalogue
effects and library terms that imitate them on this motion (a base tilt on the oscillation;
products of the force and the rates; on the rate table, a quadratic nonlinearity that fits
the moves between poses, where alone the growing delay shows), before the bench stage looks,
and library terms sometimes whole (a 100 ppm drift on the rate table left nothing in the
final residual, but a growth of 50–58 ppm beside the catalogue's time_skew and nonlinearity).
So where the model claims catalogue effects or discovered terms and a family is left in its
final residual or in the catalogue's (the discovered terms added back), the alternative is
built: the families found in the first-order residual (beside bias and K,
``motion_families.find_families``) are taken out of the samples (the delay's growth only)
and the whole diagnosis is run again on what is left. The catalogue's own residual is the
trigger, not the first-order one: a true catalogue effect that is a function of the angles
(k2·f_z² on the oscillation is a twice-per-turn harmonic of the middle axis) leaves no
family once it is claimed, while the first-order residual holds one and its alternative,
with fewer parameters, won on BIC on 2 of 2 seeds. The alternative may claim
only the families' own nuisance (``time_skew``, the mean delay, beside a growth; nothing
beside harmonics); then the two models are compared on the recording's samples by

    BIC = n Σ_c ln σ̂²_c + k ln(3n),

σ̂²_c the residual variance of channel c over the n used samples, k the parameters beyond
bias and K (the claimed terms', 2 per harmonic and channel, 1 for the growth): the alternative
is kept when its BIC is lower (the claims only imitated the families). Otherwise the first
model stands.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bench.diagnosis.effects import CATALOGUE
from bench.diagnosis.motion_families import Families, find_families
from bench.diagnosis.result import Diagnosis
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit
from bench.estimation.dynamic_model import ModelSpec, initial_theta, predict, specific_force
from bench.estimation.motion_data import MotionData

FloatArray = np.ndarray
CATALOGUE_IDS = frozenset(e.id for e in CATALOGUE)
DRIFT_NUISANCE = "time_skew"
"""The catalogue term that holds a growing delay's mean: the alternative may claim it."""


def _bic(left: FloatArray, k: int) -> float:
    n = left.shape[0]
    return float(n * np.sum(np.log(np.var(left, axis=0))) + k * math.log(3 * n))


def kfdot(f: FloatArray, K: FloatArray, t_s: FloatArray) -> FloatArray:
    """(n, 3) K·ḟ, the raw output's rate of change from the model (channel units / s)."""
    return np.asarray(np.gradient(f, t_s, axis=0) @ K.T, dtype=float)


def _alt_theta(alt: Diagnosis, lever: FloatArray) -> tuple[ModelSpec, FloatArray]:
    claimed = tuple(x.effect for x in alt.findings if x.effect in CATALOGUE_IDS)
    spec = ModelSpec(claimed)
    theta = initial_theta(spec, alt.bias, alt.K, lever)
    for x in alt.findings:
        if x.effect == DRIFT_NUISANCE:
            theta[spec.index(DRIFT_NUISANCE)] = float(x.parameters["delay_s"])
    return spec, theta


def cannot_win(alt: Diagnosis, allowed: frozenset[str]) -> bool:
    """Whether the alternative claims more than the families' nuisance: a catalogue term not in
    ``allowed`` or a discovered term (then the first model stands, whatever the BIC)."""
    claims = any(f.effect in CATALOGUE_IDS and f.effect not in allowed for f in alt.findings)
    return claims or bool(alt.discovered)


def head_to_head(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever: FloatArray,
    baseline: DynamicFit,
    full_left: FloatArray,
    k_full: int,
    rerun: Callable[[FloatArray, frozenset[str]], Diagnosis | None],
    th: Thresholds = THRESHOLDS,
) -> tuple[Diagnosis, Families, FloatArray, str] | None:
    """The alternative diagnosis, its families, its residual and a note, when it beats the full model.

    :param baseline: the first-order fit (bias and K only).
    :param full_left: (n_used, 3) the full model's residual less its families (used samples).
    :param k_full: parameters of the full model beyond bias and K (families included).
    :param rerun: (samples, the catalogue terms the alternative may claim) -> the diagnosis of
        them without this head to head, or ``None`` once it is known to claim another catalogue
        term or a discovered one (it cannot win: :func:`cannot_win`).
    """
    ok = np.asarray(m.valid, dtype=bool)
    model0, _ = predict(baseline.theta, m, baseline.spec, g_m_s2, lever)
    f0 = specific_force(baseline.theta, m, baseline.spec, g_m_s2, lever)
    r0 = y - model0
    good = ok & np.all(np.isfinite(r0), axis=1)
    kf0 = kfdot(f0, baseline.theta[3:12].reshape(3, 3), m.t_s)
    fam = find_families(r0[good], f0[good], kf0[good], m.angles_rad[good], m.t_s[good], th)
    if fam.empty:
        return None
    y_alt = y - fam.signal(m.angles_rad, kf0, m.t_s)
    allowed = frozenset({DRIFT_NUISANCE} if fam.drift is not None else ())
    alt = rerun(y_alt, allowed)
    if alt is None or cannot_win(alt, allowed):
        return None
    spec, theta = _alt_theta(alt, lever)
    pred, _ = predict(theta, m, spec, g_m_s2, lever)
    left_alt = (y_alt - pred)[good]
    k_alt = fam.n_params + spec.n_params - 12
    bic_alt, bic_full = _bic(left_alt, k_alt), _bic(full_left, k_full)
    if not bic_alt < bic_full:
        return None
    what = " and ".join(
        w
        for w, on in (("the angle harmonics", fam.harmonics), ("the delay's growth", fam.drift is not None))
        if on
    )
    note = (
        f"bench families against the catalogue: {what} beside bias and K"
        f"{' and the mean delay' if spec.terms else ''} (BIC {bic_alt:.1f}) explain the samples better "
        f"than the catalogue's claims with them (BIC {bic_full:.1f}); the claims only imitated them and "
        "are withdrawn"
    )
    return alt, fam, left_alt, note
