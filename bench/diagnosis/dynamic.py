"""Diagnosis of a moving-table recording (``rate-1axis``, ``oscillation-2axis``).

Baseline: raw = b + K f with f from the believed geometry (the sidecar's lever arm, level
table, no skew), fitted to every usable sample by the dynamic batch fit
(``bench.estimation.dynamic_batch``). Candidates: the dynamic model's terms
(``dynamic_model.TERM_ORDER``) that the motion determines (Fisher information of the
extended model of full rank, ``observability``). Greedy forward selection, as for static
windows: every candidate is fitted, its departure δ from the baseline value

    lever_arm: r − r_sidecar (3);  proof_mass_offsets: q_i − mean(q) (rank 6, only once
    the lever arm is in);  nonlinearity_quadratic: k2 (3);  table_tilt: (a, b);  time_skew: δ

is judged by a Wald statistic W = δᵀ Cov(δ)⁻¹ δ with the fit's sandwich covariance (it
carries the recording's own coloured noise: bias wander over the score blocks) against
χ²_q at false_alarm / N (N candidates in the step); it enters if W passes and its BIC
change, 3 n_used Σ_c ln(σ̂²_c,1 / σ̂²_c,0) / 3 + q ln(3 n_used), is negative.

``sensor_lowpass``: a first-order low-pass τ ẏ = x − y is, for ωτ ≪ 1, y ≈ x − τ ẋ, the
same signature as a delay of τ; at the procedures' rates (ωτ < 0.01) the two cannot be
told apart, so a delay found is reported as ``time_skew`` confounded with ``sensor_lowpass``.

After the catalogue, the moving term library (``library_motion``, searched by
``library_motion_search``, reported in ``discovered``); where a discovered term makes the
catalogue's later steps redundant, the catalogue path is cut back (``library_motion_swap``).
``claim_catalogue`` is that claim; it runs the moving stages (``dynamic_selection``:
screen_motion, motion_selection on the selection core ``greedy``, library_cut). The bench
families are then weighed against it (``family_referee``'s head to head, which may withdraw
it): :func:`claim_moving` is the whole claim, shared with ``calibrate``'s term selection, so
a calibration fits exactly the terms the diagnosis claims.

Residuals and correlates: 1 s block means of the baseline residuals (the "windows" of the
report) against ω² = −tr(B_sym)/2, |ω̇| (from the antisymmetric part of B), f_i², |f_i|, time
and temperature, by ``regressors.block_correlations``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.diagnosis.bench_families import moving_stage as bench_stage
from bench.diagnosis.dynamic_selection import (
    CatalogueClaim,
    TermSelection,
    claim_catalogue,
    departure,
    select_terms,
)
from bench.diagnosis.dynamic_summary import block_summary, motion_regressors, unexplained_blocks
from bench.diagnosis.effects import CATALOGUE
from bench.diagnosis.library_motion_search import discovery
from bench.diagnosis.residuals import where_text
from bench.diagnosis.result import Diagnosis, Finding
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit, white_sigma
from bench.estimation.motion_data import MotionData

__all__ = [
    "CatalogueClaim",
    "MovingClaim",
    "TermSelection",
    "claim_catalogue",
    "claim_moving",
    "diagnose_dynamic",
    "select_terms",
]

FloatArray = np.ndarray
CHANNELS = ("ax", "ay", "az")
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


@dataclass(frozen=True)
class MovingClaim:
    """What a moving recording's diagnosis claims, shared with ``calibrate``: the catalogue's
    claim (``claim_catalogue``) and the bench families beside it, or, where the families' head
    to head (``family_referee``) withdraws that claim, the diagnosis that won it.

    :param catalogue: the catalogue's claim before the head to head.
    :param bench: the bench families' findings beside it (empty when it was withdrawn, or not
        asked for: ``claim_moving(findings=False)``).
    :param alternative: the diagnosis of the samples without the families, whose claims
        replace the catalogue's, when it won the head to head; else ``None``.
    """

    catalogue: CatalogueClaim
    bench: tuple[Finding, ...]
    alternative: Diagnosis | None

    @property
    def terms(self) -> tuple[str, ...]:
        """The dynamic model's terms the diagnosis claims, in order."""
        if self.alternative is None:
            return self.catalogue.terms
        return tuple(f.effect for f in self.alternative.findings if f.effect in PARAM)

    @property
    def withdrawn(self) -> str | None:
        """Why the catalogue's claim was withdrawn (the head to head's note), or ``None``."""
        return None if self.alternative is None else self.alternative.notes[0]


def claim_moving(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever_arm_m: FloatArray,
    *,
    temp_c: FloatArray | None = None,
    unit: str = "",
    channel_unit: str = "",
    source: str = "",
    library: bool = True,
    thresholds: Thresholds = THRESHOLDS,
    head_to_head: bool = True,
    findings: bool = True,
) -> MovingClaim:
    """The claim of :func:`diagnose_dynamic` (same arguments): the catalogue claim, then the
    bench families on its final residual and, where it claims something and a family is left,
    their head to head against it (``bench_families.moving_stage``). ``findings`` False (the
    claim alone, for ``calibrate``): a claim of nothing has no head to head and the families
    are not searched (``bench`` is then empty)."""
    lever = np.asarray(lever_arm_m, dtype=float).reshape(3)
    th = thresholds
    claim = claim_catalogue(m, y, g_m_s2, lever, temp_c, library=library, th=th)
    lib, vals = claim.library, claim.values
    if not findings and not (claim.k or lib.included):
        return MovingClaim(claim, (), None)
    bench_found, alternative = bench_stage(
        m, y, g_m_s2, lever, claim.fits[-1], lib.adjustment(vals) if lib.included else None, channel_unit, th,
        baseline=claim.selection.fits[0], n_claims=claim.k + len(lib.included), n_library=len(lib.included),
        rerun=None if not head_to_head else lambda y2: diagnose_dynamic(
            m, y2, g_m_s2, lever_arm_m, temp_c=temp_c, unit=unit, channel_unit=channel_unit, source=source,
            library=library, thresholds=th, head_to_head=False,
        ),
    )  # fmt: skip
    return MovingClaim(claim, () if alternative is not None else tuple(bench_found), alternative)


def diagnose_dynamic(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever_arm_m: FloatArray,
    *,
    temp_c: FloatArray | None = None,
    unit: str = "",
    channel_unit: str = "",
    source: str = "",
    library: bool = True,
    thresholds: Thresholds = THRESHOLDS,
    head_to_head: bool = True,
) -> Diagnosis:
    """Diagnose a moving-table recording (module docstring).

    :param m: the motion (``motion_data.prepare_motion``); :param y: (n, 3) raw samples.
    :param lever_arm_m: (3,) the lever arm the recording believes (m).
    :param temp_c: (n,) temperature (°C) or ``None``.
    :param library: search the moving library after the catalogue (``library_motion``).
    :param head_to_head: a bench family found beside catalogue claims is weighed against them
        by running the diagnosis again without it (``family_referee``).
    :param thresholds: the diagnosis's knobs (``thresholds``).
    :raises ValueError: a motion that cannot determine bias and K.
    """
    lever = np.asarray(lever_arm_m, dtype=float).reshape(3)
    sig_w = np.maximum(white_sigma(y[m.valid]), 1e-12)
    th = thresholds
    whole = claim_moving(
        m, y, g_m_s2, lever_arm_m, temp_c=temp_c, unit=unit, channel_unit=channel_unit, source=source,
        library=library, thresholds=th, head_to_head=head_to_head,
    )  # fmt: skip
    if whole.alternative is not None:
        return whole.alternative
    claim = whole.catalogue
    sel, k_cut, lib, vals, cut_note = claim.selection, claim.k, claim.library, claim.values, claim.note
    unobservable = {**STATIC_ONLY, **sel.unobservable}
    n_obs = 3 * int(m.valid.sum())
    fits = list(claim.fits)
    steps = list(sel.steps[:k_cut])
    final = fits[-1]
    findings = []
    for k, (t, dbic, w) in enumerate(steps):
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
    discovered = tuple(discovery(inc, final, channel_unit) for inc in lib.included)
    findings += whole.bench
    regs = motion_regressors(m, y, final, g_m_s2, lever, temp_c)
    bs = block_summary(
        m, y, fits, g_m_s2, lever, sig_w, regs, n_obs,
        library=lib.adjustment(vals) if lib.included else None,
        library_terms=tuple(i.term.label for i in lib.included), th=th,
    )  # fmt: skip
    notes = (
        "sensor_lowpass: a low-pass of time constant τ looks like a delay of τ at these rates; "
        "a delay found is reported as time_skew",
        f"noise: white sigma from the samples' second differences [{', '.join(f'{v:.3g}' for v in sig_w)}] "
        "channel units; parameter sigmas from the batch fit's sandwich covariance (coloured noise included)",
        *lib.notes,
        *((cut_note,) if cut_note else ()),
    )
    unexplained = unexplained_blocks(bs, th)
    limit = f"{th.where_z:g} sigma in a {th.block_s:g} s block mean"
    return Diagnosis(
        unit=unit,
        channel_unit=channel_unit,
        method="dynamic",
        baseline=bs.baseline,
        final=bs.final,
        findings=tuple(findings),
        channel_ratio=bs.channel_ratio,
        where=where_text(bs.where, bs.where_beyond, bool(findings or discovered or unexplained), limit),
        correlations=bs.correlations,
        unobservable=unobservable,
        notes=notes,
        noise_text=notes[1],
        labels=bs.labels,
        mid_s=bs.mid_s,
        bias=final.theta[:3].copy(),
        K=final.theta[3:12].reshape(3, 3).copy(),
        source=source,
        discovered=discovered,
        unexplained=unexplained,
    )
