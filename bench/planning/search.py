"""The planner: the static design that meets the targets in the least table time.

Candidates are :func:`~bench.procedures.planned.planned_static` procedures (twelve icosahedron
directions in antipodal order, ``repeats`` passes, ``dwell_s`` per visit). Each is walked on the
table's limits by :func:`~bench.procedures.preview.preview` — the same timing the sequencer's
preview gives, moves and settling included — and its window times and forces give the predicted
covariance of the static window fit with the unit's coloured noise
(:func:`~bench.planning.evaluation.evaluate`). For every dwell of
:data:`DWELL_GRID_S` the fewest passes that meet every target are found by bisection (the
covariance only shrinks with more passes); the shortest candidate wins. Each design is reported
against the white-noise bound of any motion for the same table time.

Cost (docs/benchmarks.md): once a design meets the targets, a later dwell is searched only over
the passes that are shorter than it (none when one pass is not), and one pass that meets is the
dwell's answer without evaluating the longest design. For the every-sample fit the longest
design's trajectory is sampled once per dwell and the shorter designs take its first samples
(``bench.planning.sampled``). A design whose closed-form floor (``bench.planning.floors``: the
white-noise bound of any motion over the time its fit weighs, the wander-limited bias bound
over its span) already misses a target is passed over unevaluated, and with it the dwell's
designs of fewer passes; when no design meets the targets, the closest (the least RMS σ(K_ij)
of every dwell's longest design) evaluates a dwell only while its floor is below the closest
found so far (:func:`_closest`). None of this changes the chosen or the closest design.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from bench.planning.evaluation import (
    EVERY_SAMPLE_FS_HZ,
    Evaluation,
    Fit,
    Targets,
    evaluate,
)
from bench.planning.every_sample import BLOCK_S
from bench.planning.floors import Floor, floor
from bench.planning.information import PredictedUncertainty
from bench.planning.noise import UnitNoise
from bench.planning.sampled import SampledTrajectory
from bench.procedures.planned import MAX_WINDOWS, planned_static, planned_tumble
from bench.procedures.preview import DEFAULT_TABLE_LIMITS, Preview, TableLimits, preview
from bench.procedures.steps import Dwell, MoveTo, Procedure
from bench.records import WindowKind

FAMILY = {"window": planned_static, "every-sample": planned_tumble}
"""The procedure each fit family plans: planned-static (window fit), planned-tumble (every sample)."""

DWELL_GRID_S = (2.0, 3.0, 5.0, 8.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0)
"""Dwell per visit tried by :func:`plan` (s)."""
DEFAULT_SETTLE_S = 2.0
"""Settling after each move planned on a table whose limits state none (s): the procedures' own."""


def settle_for(limits: TableLimits, settle_s: float | None) -> float:
    """The settling planned after each move (s): ``settle_s`` when given (the preview refuses
    one shorter than the table's), else the table's (``limits.settle_s``), else
    :data:`DEFAULT_SETTLE_S`."""
    if settle_s is not None:
        return settle_s
    return limits.settle_s if limits.settle_s > 0 else DEFAULT_SETTLE_S


@dataclass(frozen=True)
class Plan:
    """The chosen design, or why none met the targets.

    :param best: the shortest design that met every target, ``None`` when none did.
    :param closest: when none did, of every dwell's longest design within the cap the one of
        least RMS σ(K_ij) (what is reachable).
    :param problems: one sentence each when a target is out of reach.
    """

    best: Evaluation | None
    closest: Evaluation | None
    problems: tuple[str, ...] = field(default_factory=tuple)


def plan(
    noise: UnitNoise,
    targets: Targets,
    *,
    limits: TableLimits = DEFAULT_TABLE_LIMITS,
    settle_s: float | None = None,
    g_m_s2: float = 9.80665,
    with_tilt: bool = True,
    max_duration_s: float = 2 * 3600.0,
    fits: tuple[Fit, ...] = ("window",),
) -> Plan:
    """The shortest planned-static design within ``max_duration_s`` of table time that meets
    ``targets`` under any of ``fits`` (module docstring); the chosen :class:`Evaluation` names
    its fit. ``settle_s``: :func:`settle_for`."""
    settle = settle_for(limits, settle_s)
    chosen = [_plan_one(noise, targets, limits, settle, g_m_s2, with_tilt, max_duration_s, f) for f in fits]
    met = [p for p in chosen if p.best is not None]
    if met:
        return min(met, key=lambda p: p.best.duration_s if p.best is not None else math.inf)
    return min(chosen, key=lambda p: p.closest.predicted.k_rms if p.closest is not None else math.inf)


@dataclass
class Designs:
    """One fit family's designs (``FAMILY[fit]`` with ``dwell_s`` and ``repeats``) for one unit and
    table: each built, walked and evaluated at most once.

    :ivar sampled: per dwell, the every-sample trajectory of its longest design, whose first
        samples the shorter designs take (``bench.planning.sampled``).
    """

    noise: UnitNoise
    limits: TableLimits
    settle_s: float
    g_m_s2: float
    with_tilt: bool
    fit: Fit
    sampled: dict[float, SampledTrajectory] = field(default_factory=dict)
    evaluated: dict[tuple[float, int], Evaluation] = field(default_factory=dict)
    walked: dict[tuple[float, int], Preview] = field(default_factory=dict)

    def procedure(self, dwell_s: float, repeats: int) -> Procedure:
        """The design of ``repeats`` passes of ``dwell_s`` s per visit."""
        return FAMILY[self.fit](dwell_s=dwell_s, repeats=repeats, settle_s=self.settle_s)

    def walk(self, dwell_s: float, repeats: int) -> Preview:
        """The design walked on the limits (:func:`~bench.procedures.preview.preview`)."""
        key = (dwell_s, repeats)
        if key not in self.walked:
            self.walked[key] = preview(self.procedure(dwell_s, repeats), self.limits)
        return self.walked[key]

    def duration_s(self, dwell_s: float, repeats: int) -> float:
        """The design's table time on the limits, moves and settling included (s)."""
        return self.walk(dwell_s, repeats).duration_s

    def evaluate(self, dwell_s: float, repeats: int) -> Evaluation:
        """The design's prediction (:func:`~bench.planning.evaluation.evaluate`), on the first
        samples of the dwell's longest design when it has been sampled."""
        key = (dwell_s, repeats)
        if key not in self.evaluated:
            self.evaluated[key] = evaluate(
                self.procedure(dwell_s, repeats),
                self.noise,
                limits=self.limits,
                g_m_s2=self.g_m_s2,
                with_tilt=self.with_tilt,
                fit=self.fit,
                sampled=self.sampled.get(dwell_s),
            )
        return self.evaluated[key]

    def sample_longest(self, dwell_s: float, repeats: int) -> None:
        """Sample the every-sample trajectory of the dwell's longest design (``repeats`` passes)."""
        proc = self.procedure(dwell_s, repeats)
        self.sampled[dwell_s] = SampledTrajectory.sample(proc, EVERY_SAMPLE_FS_HZ, self.limits, self.g_m_s2)

    def longest(self, dwell_s: float, repeats: int) -> Evaluation:
        """The prediction of the dwell's longest design (``repeats`` passes), on its own samples."""
        if self.fit == "every-sample" and repeats > 1 and dwell_s not in self.sampled:
            self.sample_longest(dwell_s, repeats)
        return self.evaluate(dwell_s, repeats)

    def floor(self, dwell_s: float, repeats: int) -> Floor:
        """What the design's prediction cannot go below (:func:`floor`), from its walk alone:
        the window fit weighs its static windows' time; the every-sample fit its samples' span,
        taken from the dwell's samples when they are there, else at most the table time and half
        a sample per move, settling and dwell (each is sampled to the nearest sample)."""
        pv = self.walk(dwell_s, repeats)
        if self.fit == "window":
            info_s = sum(w.duration_s for w in pv.windows if w.kind == WindowKind.STATIC)
            return floor(self.noise, info_s, pv.duration_s, self.g_m_s2)
        s = self.sampled.get(dwell_s)
        proc = self.procedure(dwell_s, repeats)
        if s is not None and s.begins(proc):
            span_s = int(s.step_ends[len(proc.steps) - 1]) / s.fs_hz
        else:
            pieces = sum(
                2 if isinstance(x, MoveTo) else 1 for x in proc.steps if isinstance(x, MoveTo | Dwell)
            )
            span_s = pv.duration_s + 0.5 * pieces / EVERY_SAMPLE_FS_HZ
        return floor(self.noise, span_s, span_s + BLOCK_S, self.g_m_s2)

    def cannot_meet(self, targets: Targets, dwell_s: float, repeats: int) -> bool:
        """No prediction of the design, nor of one with fewer passes, meets ``targets``: its
        :meth:`floor` already misses one (the floors only rise as the passes fall)."""
        return self.floor(dwell_s, repeats).misses(targets)


def _passes_within(designs: Designs, dwell_s: float, max_duration_s: float) -> int | None:
    """The most passes of ``dwell_s``, at most :data:`MAX_WINDOWS` / 12, whose table time is
    within the cap; ``None`` when one pass is not. (A later pass takes a little longer than the
    first, whose first move starts from the table's zero: passes × one pass's time is only the
    start of the bisection.)"""
    per_pass = designs.duration_s(dwell_s, 1)
    hi = max(1, min(MAX_WINDOWS // 12, int(max_duration_s // per_pass)))
    return _passes_shorter_than(designs, dwell_s, hi, math.nextafter(max_duration_s, math.inf))


def _passes_shorter_than(designs: Designs, dwell_s: float, hi: int, duration_s: float) -> int | None:
    """The most passes, at most ``hi``, whose design is shorter than ``duration_s``; ``None`` when
    one pass is not (bisection: the table time grows with the passes)."""
    if designs.duration_s(dwell_s, 1) >= duration_s:
        return None
    if designs.duration_s(dwell_s, hi) < duration_s:
        return hi
    lo, top = 1, hi  # invariant: lo passes are shorter than duration_s, top are not
    while top - lo > 1:
        mid = (lo + top) // 2
        if designs.duration_s(dwell_s, mid) < duration_s:
            lo = mid
        else:
            top = mid
    return lo


def _fewest_passes(
    designs: Designs, targets: Targets, dwell_s: float, hi: int
) -> tuple[Evaluation | None, Evaluation | None]:
    """(the design of the fewest passes, at most ``hi``, that meets ``targets``, or ``None``; the
    ``hi``-pass design when one pass does not meet them, else ``None``). ``(None, None)``: the
    ``hi``-pass design's floor misses a target, so no design of the dwell meets them (none is
    evaluated but one pass, and that only when its floor does not miss).

    Bisection over the passes: the covariance only shrinks with more of them.
    """
    if not designs.cannot_meet(targets, dwell_s, 1):
        one = designs.evaluate(dwell_s, 1)
        if targets.met_by(one.predicted):
            return one, None
    if designs.cannot_meet(targets, dwell_s, hi):  # nor can any with fewer passes
        return None, None
    top = designs.longest(dwell_s, hi)
    if not targets.met_by(top.predicted):
        return None, top
    met, lo = top, 1  # invariant: `met` (hi passes) meets, lo passes do not
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if designs.cannot_meet(targets, dwell_s, mid):
            lo = mid
            continue
        e = designs.evaluate(dwell_s, mid)
        if targets.met_by(e.predicted):
            hi, met = mid, e
        else:
            lo = mid
    return met, top


def _plan_one(
    noise: UnitNoise,
    targets: Targets,
    limits: TableLimits,
    settle_s: float,
    g_m_s2: float,
    with_tilt: bool,
    max_duration_s: float,
    fit: Fit,
) -> Plan:
    """The shortest design of one fit family that meets ``targets`` (module docstring)."""
    runs = preview(FAMILY[fit](dwell_s=DWELL_GRID_S[0], repeats=1, settle_s=settle_s), limits)
    if runs.problems:  # a pose beyond an axis's travel, a settling shorter than the table's
        name = FAMILY[fit].__name__.replace("_", "-")
        return Plan(None, None, tuple(f"{name} does not fit this table: {p}" for p in runs.problems))
    designs = Designs(noise, limits, settle_s, g_m_s2, with_tilt, fit)
    best: Evaluation | None = None
    longest: list[tuple[float, int, Evaluation | None]] = []  # while none meets: each dwell's longest
    for dwell in DWELL_GRID_S:
        within = _passes_within(designs, dwell, max_duration_s)
        if within is None:
            continue
        hi = within
        if best is not None:
            # only a design shorter than the best so far can take its place
            shorter = _passes_shorter_than(designs, dwell, hi, best.duration_s)
            if shorter is None:
                continue
            hi = shorter
        met, top = _fewest_passes(designs, targets, dwell, hi)
        if best is None and met is None:  # top None: not evaluated, none of the dwell can meet
            longest.append((dwell, hi, top))
        if met is not None and (best is None or met.duration_s < best.duration_s):
            best = met
    if best is not None:
        return Plan(best, None)
    return _none_meets(_closest(designs, longest), max_duration_s)


def _none_meets(closest: Evaluation | None, max_duration_s: float) -> Plan:
    """The plan when no design meets the targets: the closest design and why."""
    problem = (
        "no planned design within "
        f"{max_duration_s / 60:.0f} min meets the targets; the best reaches "
        + describe_sigmas(closest.predicted)
        if closest is not None
        else f"no planned design fits within {max_duration_s / 60:.3g} min (one pass of the shortest dwell)"
    )
    return Plan(None, closest, (problem,))


def _closest(designs: Designs, longest: list[tuple[float, int, Evaluation | None]]) -> Evaluation | None:
    """Of each dwell's longest design ((dwell, passes, its prediction or ``None`` when not yet
    evaluated), in :data:`DWELL_GRID_S` order), the one of least RMS σ(K_ij), the first on a tie.

    A design not yet evaluated is evaluated only while its :meth:`Designs.floor` is not above
    the least found so far (the floor's ``k`` bounds the RMS from below), in order of the floors:
    the same design as evaluating them all.
    """
    chosen: tuple[float, int, Evaluation] | None = None
    for i, (_, _, e) in enumerate(longest):
        if e is not None and (chosen is None or (e.predicted.k_rms, i) < chosen[:2]):
            chosen = (e.predicted.k_rms, i, e)
    pending = sorted((designs.floor(d, r).k, i) for i, (d, r, e) in enumerate(longest) if e is None)
    for k_floor, i in pending:
        if chosen is not None and k_floor > chosen[0]:
            break
        dwell, reps, _ = longest[i]
        e = designs.longest(dwell, reps)
        if chosen is None or (e.predicted.k_rms, i) < chosen[:2]:
            chosen = (e.predicted.k_rms, i, e)
    return None if chosen is None else chosen[2]


def describe_sigmas(u: PredictedUncertainty) -> str:
    """U (k = 2) per group in µg, ppm and µrad."""
    ug = 1e6 / 9.80665
    return (
        f"U(k=2) bias {2 * u.bias * ug:.3g} ug, scale {2e6 * u.scale:.3g} ppm, "
        f"misalignment {2e6 * u.misalignment:.3g} urad"
    )


def best_within(
    noise: UnitNoise,
    duration_s: float,
    *,
    limits: TableLimits = DEFAULT_TABLE_LIMITS,
    settle_s: float | None = None,
    g_m_s2: float = 9.80665,
    with_tilt: bool = True,
    fit: Fit = "window",
) -> Evaluation:
    """The planned-static design with the smallest RMS σ(K_ij) under ``fit`` whose table time
    fits ``duration_s``.

    For each dwell of :data:`DWELL_GRID_S` the most passes that fit are taken.

    ``settle_s``: :func:`settle_for`.

    :raises ValueError: not even one pass of the shortest dwell fits.
    """
    settle_s = settle_for(limits, settle_s)
    best: Evaluation | None = None
    for dwell in DWELL_GRID_S:
        one = FAMILY[fit](dwell_s=dwell, repeats=1, settle_s=settle_s)
        per_pass = preview(one, limits).duration_s
        reps = min(MAX_WINDOWS // 12, int(duration_s // per_pass))
        while reps >= 1:
            proc = FAMILY[fit](dwell_s=dwell, repeats=reps, settle_s=settle_s)
            if preview(proc, limits).duration_s <= duration_s:
                break
            reps -= 1
        if reps < 1:
            continue
        e = evaluate(proc, noise, limits=limits, g_m_s2=g_m_s2, with_tilt=with_tilt, fit=fit)
        if best is None or e.predicted.k_rms < best.predicted.k_rms:
            best = e
    if best is None:
        raise ValueError(f"no planned design fits in {duration_s:g} s (one pass of 12 poses is longer)")
    return best
