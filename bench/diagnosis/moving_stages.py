"""The stages of a moving-table diagnosis (``rate-1axis``, ``oscillation-2axis``), one rule each.

Each stage is ``stage(evidence, state, thresholds) -> (state, notes)`` (``pipeline``), like the
window-means stages (``stages``): the claim (the motion screen, the greedy selection on the
selection core ``greedy``, the moving library and the cut of catalogue steps it explains
better), the bench families on the claimed model's residual, and the 1 s block summary with
what the final model leaves unexplained. ``dynamic`` puts them in order (its pipelines, with
the families' head to head, which runs the diagnosis again) and ``moving_report`` builds the
report from the final state. The statistics: ``dynamic`` module docstring.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from bench.diagnosis.bench_families import MovingSearch, moving_search
from bench.diagnosis.dynamic_selection import (
    CatalogueClaim,
    TermSelection,
    catalogue_span,
    forward_terms,
    screen_terms,
)
from bench.diagnosis.dynamic_summary import BlockSummary, block_summary, motion_regressors, unexplained_blocks
from bench.diagnosis.library_motion_search import MotionLibraryResult, refit_terms, search_motion_library
from bench.diagnosis.library_motion_swap import cut_catalogue, fit_bic
from bench.diagnosis.pipeline import Notes
from bench.diagnosis.result import Diagnosis, Unexplained
from bench.diagnosis.thresholds import Thresholds
from bench.estimation.dynamic_batch import white_sigma
from bench.estimation.motion_data import MotionData

FloatArray = np.ndarray


@dataclass(frozen=True)
class MovingEvidence:
    """What a moving recording's diagnosis works from.

    :param motion: the motion (``motion_data.prepare_motion``); :param y: (n, 3) raw samples.
    :param g_m_s2: local gravity; :param lever_arm_m: (3,) the lever arm the recording believes (m).
    :param temp_c: (n,) temperature (°C) or ``None``.
    :param unit: the unit's serial, :param channel_unit: the samples' unit, :param source: the
        recording's path: the report's labels.
    """

    motion: MotionData
    y: FloatArray
    g_m_s2: float
    lever_arm_m: FloatArray
    temp_c: FloatArray | None = None
    unit: str = ""
    channel_unit: str = ""
    source: str = ""

    @cached_property
    def white_sigma(self) -> FloatArray:
        """(3,) the samples' white sigma from their second differences (channel units), ≥ 1e-12."""
        return np.maximum(white_sigma(self.y[self.motion.valid]), 1e-12)

    @property
    def n_obs(self) -> int:
        """3 × the samples the fit uses."""
        return 3 * int(self.motion.valid.sum())


@dataclass(frozen=True)
class MovingState:
    """What the moving stages have decided so far.

    :param pool: the terms the motion determines; :param unobservable: term -> why the others
        are not; :param selection: the greedy selection; :param claim: the claim (its steps and
        the library's terms).
    :param families: the bench families on the claim's residual (``bench_families.moving_search``).
    :param alternative: the diagnosis without the families, when it won the head to head
        against the claim (its report replaces this one), else ``None``.
    :param blocks: the block summary (``dynamic_summary``); :param left: what the final model
        leaves unexplained, or ``None``.
    :param notes: label -> why it was set aside.
    """

    pool: tuple[str, ...] = ()
    unobservable: dict[str, str] = field(default_factory=dict)
    selection: TermSelection | None = None
    claim: CatalogueClaim | None = None
    families: MovingSearch | None = None
    alternative: Diagnosis | None = None
    blocks: BlockSummary | None = None
    left: Unexplained | None = None
    notes: dict[str, str] = field(default_factory=dict)

    def noted(self, notes: Notes) -> MovingState:
        """The state with ``notes`` added (a label's later note replaces an earlier one)."""
        return replace(self, notes={**self.notes, **notes}) if notes else self

    @property
    def claimed(self) -> CatalogueClaim:
        """The claim (after ``library_cut`` or ``claim_all``)."""
        assert self.claim is not None
        return self.claim


def screen_motion(ev: MovingEvidence, st: MovingState, th: Thresholds) -> tuple[MovingState, Notes]:
    """Motion screen. Rule: a term of the dynamic model is a candidate only where the motion
    determines it (the Fisher information of the extended model is of full rank)."""
    pool, unobservable = screen_terms(ev.motion, ev.y, ev.g_m_s2, ev.lever_arm_m)
    return replace(st, pool=pool, unobservable={**st.unobservable, **unobservable}), {}


def motion_selection(ev: MovingEvidence, st: MovingState, th: Thresholds) -> tuple[MovingState, Notes]:
    """Greedy forward selection (``greedy.forward``). Rule: at each step every candidate is
    fitted; it enters if its Wald statistic (sandwich covariance) passes χ²_q at
    ``th.false_alarm`` / N and its BIC change is negative, the lowest BIC change first."""
    sel = forward_terms(ev.motion, ev.y, ev.g_m_s2, ev.lever_arm_m, st.pool, st.unobservable, th)
    return replace(st, selection=sel), {}


def claim_all(ev: MovingEvidence, st: MovingState, th: Thresholds) -> tuple[MovingState, Notes]:
    """Claim without a library. Rule: every selected step is claimed."""
    sel = st.selection
    assert sel is not None
    empty = MotionLibraryResult((), sel.fits[-1:], 0, ())
    return replace(st, claim=CatalogueClaim(sel, len(sel.steps), empty, {}, None)), {}


def library_cut(ev: MovingEvidence, st: MovingState, th: Thresholds) -> tuple[MovingState, Notes]:
    """Moving library and catalogue cut (``library_motion_search``, ``library_motion_swap``).
    Rule: the moving library is searched after the catalogue (its own gates); where a shorter
    catalogue path with the library's terms has a BIC lower by more than ``th.tie_chi2``, the
    later catalogue steps are replaced."""
    sel = st.selection
    assert sel is not None
    m, y, g, lever = ev.motion, ev.y, ev.g_m_s2, ev.lever_arm_m

    def search(k: int) -> tuple[MotionLibraryResult, dict[str, FloatArray]]:
        span = catalogue_span(sel, lever, k)
        return search_motion_library(m, y, g, lever, sel.fits[k], ev.temp_c, span, th=th)

    def rescore(k: int, full: MotionLibraryResult, vals: dict[str, FloatArray]) -> float:
        coef = np.array([i.coefficient for i in full.included])
        terms = [i.term for i in full.included]
        return fit_bic(refit_terms(m, y, g, lever, sel.fits[k], terms, coef, vals, th)[0], len(terms))

    k, lib, vals, note = cut_catalogue(search, rescore, len(sel.steps), sel.chosen, th)
    return replace(st, claim=CatalogueClaim(sel, k, lib, vals, note)), {}


def bench_physics(ev: MovingEvidence, st: MovingState, th: Thresholds) -> tuple[MovingState, Notes]:
    """Bench families (``bench_families.moving_search``, ``motion_families``). Rule: in the
    claimed model's residual (the discovered terms taken out), a disturbance locked to a table
    axis's angle and a delay that grows along the run are claimed where their tests pass at
    ``th.bench_false_alarm``, then a periodic line in what they leave where its periodogram
    peak passes the line test; they do not change the claim."""
    claim = st.claimed
    fams = moving_search(
        ev.motion, ev.y, ev.g_m_s2, ev.lever_arm_m, claim.fits[-1], claim.library_signal, ev.channel_unit, th
    )
    return replace(st, families=fams), {}


def block_residuals(ev: MovingEvidence, st: MovingState, th: Thresholds) -> tuple[MovingState, Notes]:
    """Block summary (``dynamic_summary.block_summary``). Rule: the first-order and the final
    model's residuals as ``th.block_s`` block means against the white noise, where the
    first-order mismatch is strongest, and the blocks' correlations with the motion's regressors
    (ω², |ω̇|, f², |f|, ḟ, time, temperature) after bias and K at ``th.correlation_significance``.
    Nothing once the families' head to head withdrew the claim: the alternative's report stands."""
    if st.alternative is not None:
        return st, {}
    claim, m = st.claimed, ev.motion
    lever = ev.lever_arm_m
    regs = motion_regressors(m, ev.y, claim.fits[-1], ev.g_m_s2, lever, ev.temp_c)
    lib = claim.library
    bs = block_summary(
        m, ev.y, list(claim.fits), ev.g_m_s2, lever, ev.white_sigma, regs, ev.n_obs,
        library=claim.library_signal, library_terms=tuple(i.term.label for i in lib.included), th=th,
    )  # fmt: skip
    return replace(st, blocks=bs), {}


def block_unexplained(ev: MovingEvidence, st: MovingState, th: Thresholds) -> tuple[MovingState, Notes]:
    """Unexplained (``dynamic_summary.unexplained_blocks``). Rule: per channel, the final model's
    residual against the white noise (above ``th.dynamic_ratio_limit``) and the coherence of its
    block means (``dynamic_coherence``, lower tail at ``th.unexplained_alpha`` / 3); where either
    fails, the channel, its strongest block and the regressors its blocks follow."""
    if st.blocks is None:
        return st, {}
    return replace(st, left=unexplained_blocks(st.blocks, th)), {}
