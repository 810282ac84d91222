"""Head to head of an angle harmonic against the catalogue's claims on a moving recording.

An angle-locked disturbance can be partly taken, before the bench stage looks, by catalogue
effects and library terms whose signatures are also functions of the table's angles (a base
tilt on the oscillation, products of the force and the rates). When the bench stage finds an
angle harmonic in a model that also claims catalogue effects or discovered terms, the
alternative is built: the harmonics found on the first-order residual (beside bias and K,
``motion_families.search_harmonics``) are taken out of the samples and the whole diagnosis is
run again on what is left. If that finds nothing beyond bias and K, the two models are
compared on the recording's samples by

    BIC = n Σ_c ln σ̂²_c + k ln(3n),

σ̂²_c the residual variance of channel c over the n used samples, k the parameters beyond
bias and K (the claimed terms' and 2 per harmonic and channel): the alternative is kept when
its BIC is lower (the claims only imitated the harmonic). Otherwise the first model stands.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bench.diagnosis.effects import CATALOGUE
from bench.diagnosis.motion_families import Harmonic, harmonic_signal, search_harmonics
from bench.diagnosis.result import Diagnosis
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit
from bench.estimation.dynamic_model import predict, specific_force
from bench.estimation.motion_data import MotionData

FloatArray = np.ndarray
CATALOGUE_IDS = frozenset(e.id for e in CATALOGUE)


def _bic(left: FloatArray, k: int) -> float:
    n = left.shape[0]
    return float(n * np.sum(np.log(np.var(left, axis=0))) + k * math.log(3 * n))


def head_to_head(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever: FloatArray,
    baseline: DynamicFit,
    full_left: FloatArray,
    k_full: int,
    rerun: Callable[[FloatArray], Diagnosis],
    th: Thresholds = THRESHOLDS,
) -> tuple[Diagnosis, tuple[Harmonic, ...], FloatArray, str] | None:
    """The alternative diagnosis, its harmonics, its residual and a note, when it beats the full model.

    :param baseline: the first-order fit (bias and K only).
    :param full_left: (n_used, 3) the full model's residual less its harmonics (used samples).
    :param k_full: parameters of the full model beyond bias and K (harmonics included).
    :param rerun: samples -> the diagnosis of them without this head to head.
    """
    ok = np.asarray(m.valid, dtype=bool)
    model0, _ = predict(baseline.theta, m, baseline.spec, g_m_s2, lever)
    f0 = specific_force(baseline.theta, m, baseline.spec, g_m_s2, lever)
    r0 = y - model0
    good = ok & np.all(np.isfinite(r0), axis=1)
    hs = search_harmonics(r0[good], f0[good], m.angles_rad[good], th)
    if not hs:
        return None
    y_alt = y - harmonic_signal(hs, m.angles_rad)
    alt = rerun(y_alt)
    if any(f.effect in CATALOGUE_IDS for f in alt.findings) or alt.discovered:
        return None
    theta = np.concatenate([alt.bias, alt.K.reshape(-1)])
    pred, _ = predict(theta, m, baseline.spec, g_m_s2, lever)
    left_alt = (y_alt - pred)[good]
    k_alt = 2 * sum(len(h.channels) for h in hs)
    bic_alt, bic_full = _bic(left_alt, k_alt), _bic(full_left, k_full)
    if not bic_alt < bic_full:
        return None
    note = (
        f"angle harmonic against the catalogue: the harmonic beside bias and K alone (BIC {bic_alt:.1f}) "
        f"explains the samples better than the catalogue's claims with it (BIC {bic_full:.1f}); the claims "
        "only imitated it and are withdrawn"
    )
    return alt, hs, left_alt, note
