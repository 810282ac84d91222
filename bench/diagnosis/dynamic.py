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
The bench families are then searched in the claimed model's residual (``bench_families``) and
weighed against the claim (``family_referee``'s head to head, which may withdraw it):
:func:`claim_moving` is that whole claim, shared with ``calibrate``'s term selection, so a
calibration fits exactly the terms the diagnosis claims.

The diagnosis is a pipeline (``pipeline``), the same method as the window-means one
(``stages``) on another kind of evidence; its stages (``moving_stages``, one rule each in its
docstring) are, in :data:`MOVING`:

1. ``screen_motion``, ``motion_selection``, ``library_cut`` (``claim_all`` without the library):
   the claim;
2. ``bench_physics``, ``family_head_to_head``: the bench families and their head to head;
3. ``block_residuals``, ``block_unexplained``: the report's block summary and what it leaves.

:func:`diagnose_dynamic` runs them and builds the report from the final state
(``moving_report``).

Residuals and correlates: 1 s block means of the baseline residuals (the "windows" of the
report) against ω² = −tr(B_sym)/2, |ω̇| (from the antisymmetric part of B), f_i², |f_i|, time
and temperature, by ``regressors.block_correlations``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bench.diagnosis.bench_families import moving_head_to_head
from bench.diagnosis.dynamic_selection import CatalogueClaim, TermSelection, select_terms
from bench.diagnosis.moving_report import PARAM, moving_report
from bench.diagnosis.moving_stages import (
    MovingEvidence,
    MovingState,
    bench_physics,
    block_residuals,
    block_unexplained,
    claim_all,
    library_cut,
    motion_selection,
    screen_motion,
)
from bench.diagnosis.pipeline import Notes, Pipeline, Stage
from bench.diagnosis.result import Diagnosis, Finding
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.motion_data import MotionData

__all__ = [
    "MOVING",
    "MOVING_NO_LIBRARY",
    "CatalogueClaim",
    "MovingClaim",
    "MovingEvidence",
    "MovingState",
    "TermSelection",
    "claim_moving",
    "diagnose_dynamic",
    "pipeline_for",
    "select_terms",
]

FloatArray = np.ndarray
Moving = Pipeline[MovingEvidence, MovingState]


def head_to_head_against(alone: Moving) -> Stage[MovingEvidence, MovingState]:
    """The ``family_head_to_head`` stage whose alternative is the diagnosis ``alone`` reports
    (the same stages without this one)."""

    def family_head_to_head(ev: MovingEvidence, st: MovingState, th: Thresholds) -> tuple[MovingState, Notes]:
        """Head to head of the bench families against the claim (``family_referee``). Rule:
        where the claim holds catalogue steps or discovered terms and a family is left in the
        final residual or in the catalogue's (the discovered terms added back), the families of
        the first-order residual are taken out of the samples and the diagnosis runs again
        without this stage; when its claims are only the families' nuisance and its BIC is lower
        than the claim's with the families, it replaces this diagnosis (the claim is withdrawn).
        The run again stops at its catalogue selection when that holds another term: the library's
        cut then keeps either those steps or a discovered term, and the alternative cannot win."""
        claim, fams = st.claimed, st.families
        assert fams is not None
        n_library = len(claim.library.included)
        if not claim.k + n_library:
            return st, {}

        def rerun(y: FloatArray, allowed: frozenset[str]) -> Diagnosis | None:
            def claims_more(s: MovingState) -> bool:
                return s.selection is not None and any(t not in allowed for t in s.selection.chosen)

            alt = replace(ev, y=y)
            out, _ = alone.run(alt, MovingState(), th, until=claims_more)
            return None if claims_more(out) else moving_report(alt, out, th)

        final = claim.fits[-1]
        won = moving_head_to_head(
            ev.motion, ev.y, ev.g_m_s2, ev.lever_arm_m, fams, claim.library_signal, ev.channel_unit, th,
            baseline=claim.selection.fits[0], n_params=len(final.theta) - 12 + n_library, rerun=rerun,
        )  # fmt: skip
        return replace(st, alternative=won), {}

    return family_head_to_head


_CLAIM: tuple[Stage[MovingEvidence, MovingState], ...] = (screen_motion, motion_selection, library_cut)
_CLAIM_NO_LIBRARY: tuple[Stage[MovingEvidence, MovingState], ...] = (
    screen_motion,
    motion_selection,
    claim_all,
)
_REPORT = (block_residuals, block_unexplained)

MOVING_ALONE: Moving = Pipeline("moving, no head to head", (*_CLAIM, bench_physics, *_REPORT))
"""The moving diagnosis without the families' head to head (the alternative it runs)."""
MOVING_NO_LIBRARY_ALONE: Moving = Pipeline(
    "moving, catalogue only, no head to head", (*_CLAIM_NO_LIBRARY, bench_physics, *_REPORT)
)
"""As :data:`MOVING_ALONE` without the moving library."""

_FAMILIES = (bench_physics, head_to_head_against(MOVING_ALONE))
_FAMILIES_NO_LIBRARY = (bench_physics, head_to_head_against(MOVING_NO_LIBRARY_ALONE))

MOVING: Moving = Pipeline("moving", (*_CLAIM, *_FAMILIES, *_REPORT))
"""A moving-table recording's diagnosis (module docstring)."""
MOVING_NO_LIBRARY: Moving = Pipeline(
    "moving, catalogue only", (*_CLAIM_NO_LIBRARY, *_FAMILIES_NO_LIBRARY, *_REPORT)
)
"""As :data:`MOVING` without the moving library (``diagnose_dynamic(library=False)``)."""


def pipeline_for(library: bool = True, head_to_head: bool = True) -> Moving:
    """The moving pipeline with or without the library and the families' head to head."""
    if head_to_head:
        return MOVING if library else MOVING_NO_LIBRARY
    return MOVING_ALONE if library else MOVING_NO_LIBRARY_ALONE


@dataclass(frozen=True)
class MovingClaim:
    """What a moving recording's diagnosis claims, shared with ``calibrate``: the catalogue's
    claim (the stages up to ``library_cut``) and the bench families beside it, or, where the families' head
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


def _evidence(
    m: MotionData, y: FloatArray, g_m_s2: float, lever_arm_m: FloatArray, temp_c: FloatArray | None,
    unit: str, channel_unit: str, source: str,
) -> MovingEvidence:  # fmt: skip
    lever = np.asarray(lever_arm_m, dtype=float).reshape(3)
    return MovingEvidence(m, y, g_m_s2, lever, temp_c, unit, channel_unit, source)


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
    findings: bool = True,
) -> MovingClaim:
    """The claim of :func:`diagnose_dynamic` (same arguments): the stages of :data:`MOVING` up to
    the families' head to head. ``findings`` False (the claim alone, for ``calibrate``): a claim
    of nothing has no head to head and the families are not searched (``bench`` is then empty)."""
    ev = _evidence(m, y, g_m_s2, lever_arm_m, temp_c, unit, channel_unit, source)
    claim_stages, families = (_CLAIM, _FAMILIES) if library else (_CLAIM_NO_LIBRARY, _FAMILIES_NO_LIBRARY)
    st, _ = Pipeline("moving claim", claim_stages).run(ev, MovingState(), thresholds)
    claim = st.claimed
    if not findings and not (claim.k or claim.library.included):
        return MovingClaim(claim, (), None)
    st, _ = Pipeline("the claim's families", families).run(ev, st, thresholds)
    assert st.families is not None
    return MovingClaim(claim, () if st.alternative is not None else st.families.findings, st.alternative)


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
    """Diagnose a moving-table recording (module docstring): its pipeline (:func:`pipeline_for`),
    then the report of the final state (``moving_report``).

    :param m: the motion (``motion_data.prepare_motion``); :param y: (n, 3) raw samples.
    :param lever_arm_m: (3,) the lever arm the recording believes (m).
    :param temp_c: (n,) temperature (°C) or ``None``.
    :param library: search the moving library after the catalogue (``library_motion``).
    :param head_to_head: a bench family found beside catalogue claims is weighed against them
        by running the diagnosis again without it (``family_referee``).
    :param thresholds: the diagnosis's knobs (``thresholds``).
    :raises ValueError: a motion that cannot determine bias and K.
    """
    ev = _evidence(m, y, g_m_s2, lever_arm_m, temp_c, unit, channel_unit, source)
    st, _ = pipeline_for(library, head_to_head).run(ev, MovingState(), thresholds)
    return moving_report(ev, st, thresholds)
