"""The report of a moving-table diagnosis, built from the final state of its stages
(``moving_stages``), as ``bench.diagnosis.diagnose`` builds a window-means one: each claimed
catalogue step with its parameters and sigmas (``dynamic_selection.departure``), the discovered
terms (``library_motion_search.discovery``), the bench families' findings, the block summary
and what the final model leaves unexplained; the effects a moving recording cannot show
(:data:`STATIC_ONLY`) and the terms the motion does not determine.
"""

from __future__ import annotations

import numpy as np

from bench.diagnosis.dynamic_selection import departure
from bench.diagnosis.effects import CATALOGUE
from bench.diagnosis.library_motion_search import discovery
from bench.diagnosis.moving_stages import MovingEvidence, MovingState
from bench.diagnosis.residuals import where_text
from bench.diagnosis.result import Diagnosis, Finding
from bench.diagnosis.thresholds import Thresholds
from bench.estimation.dynamic_batch import DynamicFit

FloatArray = np.ndarray
PARAM = {
    "lever_arm": ("r_m", "m"),
    "proof_mass_offsets": ("rho_m", "m"),
    "nonlinearity_quadratic": ("k2_per_g", "1/g"),
    "table_tilt": ("tilt_rad", "rad"),
    "time_skew": ("delay_s", "s"),
}
STATIC_ONLY = {
    "scale_asymmetry": "not a term of the dynamic model; |f_i| is shown among the residual's correlates "
    "(after bias and K), not fitted: tested on static windows",
    "cross_coupling": "f_j·f_k terms are not in the dynamic model (K's off-diagonal is the linear part): "
    "tested on static windows",
    "temperature_bias": "over one moving run the temperature changes little and, on a warm-up, follows time: "
    "as bias_drift, it cannot be told from the bias wander's own trend here",
    "bias_drift": "a linear drift over one run cannot be told from the bias wander's own trend: nothing in a "
    "moving recording measures the wander at the run's length (no still windows), and the batch fit's "
    "covariance sees the noise only at its score-block scale; time is shown among the correlates",
    "pose_error": "a moving recording has no per-window poses",
    "encoder_offset": "not a term of the dynamic model: an outer-axis offset is a turn about the rotation "
    "axis that K absorbs; a middle- or inner-axis offset tilts gravity and needs static windows",
    "settling": "tested on static windows only (needs still windows after each stop)",
}


def _params(fit: DynamicFit, term: str, lever: FloatArray) -> tuple[dict[str, object], dict[str, object]]:
    name = PARAM[term][0]
    d, C, _ = departure(fit, term, lever)
    sig = np.sqrt(np.clip(np.diag(C), 0.0, None))
    if term == "lever_arm":
        return {name: (d + lever).tolist()}, {name: sig.tolist()}
    if term == "proof_mass_offsets":
        return {name: d.reshape(3, 3).tolist()}, {name: sig.reshape(3, 3).tolist()}
    if term == "time_skew":
        return {name: float(d[0])}, {name: float(sig[0])}
    return {name: d.tolist()}, {name: sig.tolist()}


def _summary_text(term: str, p: dict[str, object], s: dict[str, object]) -> str:
    name, unit = PARAM[term]
    v, e = np.atleast_1d(np.asarray(p[name], dtype=float)), np.atleast_1d(np.asarray(s[name], dtype=float))
    k = int(np.argmax(np.abs(v) / np.maximum(e, 1e-300)))
    return f"{term}: {name} = {v.ravel()[k]:.3g} ± {e.ravel()[k]:.2g} {unit} (largest of {v.size} in sigmas)"


def moving_report(ev: MovingEvidence, st: MovingState, th: Thresholds) -> Diagnosis:
    """The diagnosis the final state ``st`` of the moving stages reports (module docstring); the
    alternative's where the families' head to head withdrew the claim."""
    if st.alternative is not None:
        return st.alternative
    claim, bs, fams = st.claimed, st.blocks, st.families
    assert bs is not None and fams is not None
    lever, sig_w = ev.lever_arm_m, ev.white_sigma
    sel, lib, cut_note = claim.selection, claim.library, claim.note
    fits = claim.fits
    final = fits[-1]
    findings = []
    for k, (t, dbic, w) in enumerate(sel.steps[: claim.k]):
        p, s = _params(final, t, lever)
        conf = ("sensor_lowpass",) if t == "time_skew" else ()
        text = _summary_text(t, p, s)
        if conf:
            text += (
                "; a first-order sensor low-pass of that time constant gives the same signature at these "
                "rates (ωτ ≪ 1), so it cannot be told from sensor_lowpass"
            )
        findings.append(
            Finding(
                effect=t,
                summary=text,
                parameters=p,
                sigma=s,
                delta_bic=float(dbic),
                lr=float(w),
                residual_rms_after=float(fits[k + 1].residual_rms),
                explanation=next(e.explanation for e in CATALOGUE if e.id == t),
                confounded_with=conf,
            )
        )
    discovered = tuple(discovery(inc, final, ev.channel_unit) for inc in lib.included)
    findings += fams.findings
    notes = (
        "sensor_lowpass: a low-pass of time constant τ looks like a delay of τ at these rates; "
        "a delay found is reported as time_skew",
        f"noise: white sigma from the samples' second differences [{', '.join(f'{v:.3g}' for v in sig_w)}] "
        "channel units; parameter sigmas from the batch fit's sandwich covariance (coloured noise included)",
        *lib.notes,
        *((cut_note,) if cut_note else ()),
    )
    unexplained = st.left
    limit = f"{th.where_z:g} sigma in a {th.block_s:g} s block mean"
    return Diagnosis(
        unit=ev.unit,
        channel_unit=ev.channel_unit,
        method="dynamic",
        baseline=bs.baseline,
        final=bs.final,
        findings=tuple(findings),
        channel_ratio=bs.channel_ratio,
        where=where_text(bs.where, bs.where_beyond, bool(findings or discovered or unexplained), limit),
        correlations=bs.correlations,
        unobservable={**STATIC_ONLY, **sel.unobservable},
        notes=notes,
        noise_text=notes[1],
        labels=bs.labels,
        mid_s=bs.mid_s,
        bias=final.theta[:3].copy(),
        K=final.theta[3:12].reshape(3, 3).copy(),
        source=ev.source,
        discovered=discovered,
        unexplained=unexplained,
    )
