"""Greedy forward selection of effects: a significance gate to admit, BIC to choose.

At each step every candidate not yet in the model is tried (fixed columns appended to the
design, ``column_step``; the pose error as a variance component, ``pose_step``). A candidate is
admitted only if it is observable (its columns not absorbed by the current design), its
statistic passes the gate at α = ``Thresholds.false_alarm`` / N (N candidates in the step) and
its BIC change is negative (``column_step`` for the fixed columns' statistic and gate,
``pose_step`` for the pose variance's).

Each step tries the groups in order and takes the first with an admissible candidate:
the catalogue's columns; the library's terms beyond the catalogue (``library``; gate at
``Thresholds.library_share`` · α / N_L, ties among alike terms to the simplest); a swap of a catalogue
effect for library terms where that lowers the BIC (``catalogue_swap``); last the pose error, a
catch-all, which must also show the scatter its physics implies on every channel. Among
the admissible candidates of a group the one with the lowest BIC change enters; selection
stops when none is admissible.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, replace

import numpy as np

from bench.diagnosis.catalogue_swap import swap_step
from bench.diagnosis.column_step import structured_step
from bench.diagnosis.effects import Candidate, first_order_design
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.greedy import NotedMove, Path, extend, resume, step_alpha
from bench.diagnosis.likelihood import GlsFit, NoiseParams
from bench.diagnosis.model_state import ModelState, Step, fit_model, scale_matrix_of
from bench.diagnosis.pose_step import pose_step
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.diagnosis.wander_cap import SlowNoiseCap


@dataclass(frozen=True)
class Selection:
    """A forward selection kept with its path (``greedy.Path``), so that a check after it (the
    catalogue's pruning, the out-of-sample referee) can take catalogue effects out of the pool
    and the selection resume without them (``greedy.resume``) instead of starting again.

    :param path: the models after each step and each step's notes.
    :param groups: the selection's groups of candidates, in the order they are asked.
    :param max_steps: most steps of the path.
    """

    path: Path[ModelState]
    groups: tuple[NotedMove[ModelState], ...]
    max_steps: int

    @property
    def model(self) -> ModelState:
        """A copy of the selected model (a check changes its copy; the path keeps its own)."""
        return self.path.last.copy()

    @property
    def notes(self) -> dict[str, str]:
        """Per candidate label, why it was not admitted (the steps of the path, in order). A
        family's note (its search unresolved at a step, ``profiled.resolve``) is dropped once a
        later step admitted it: the model's candidate then says what the search found."""
        held = {c.label for c in self.path.last.candidates if c.extra_params}
        return {k: v for k, v in self.path.noted.items() if k not in held}

    def without(self, effects: Collection[str]) -> Selection:
        """The selection resumed from the step before the first of ``effects`` entered, with
        ``effects`` no longer candidates (``greedy.resume``). The steps before stand: each of
        ``effects`` was tried at them and lost, so their gates keep the share it took."""
        out = frozenset(effects)
        path = resume(
            self.path,
            self.groups,
            self.max_steps,
            holds=lambda s: any(c.effect in out for c in s.candidates),
            without=lambda s: replace(s.copy(), excluded=s.excluded | out),
        )
        return replace(self, path=path)


def select(
    ev: StaticEvidence,
    pool: list[Candidate],
    *,
    pose_allowed: bool,
    fixed: FloatArray | None = None,
    library: list[Candidate] | None = None,
    simplicity: dict[str, int] | None = None,
    excluded: Collection[str] = (),
    th: Thresholds = THRESHOLDS,
    excess: FloatArray | None = None,
) -> Selection:
    """Run the greedy selection.

    Each step tries, in this order, and takes the first group with an admissible candidate:
    the catalogue's fixed columns (gate at ``th.false_alarm`` / N, N catalogue candidates plus
    the pose error); the library's terms (gate at ``th.library_share`` · ``th.false_alarm`` / N_L,
    N_L the library's size: a family that large must not spend the catalogue's budget);
    the pose error, a catch-all, last (its gate as the catalogue's, its BIC charged its
    effective degrees of freedom, and it must show the scatter its physics implies on every
    channel, ``catch_all``). A catalogue effect thus enters before a library term that
    would mimic it, and a structured term before a random effect that could absorb it.

    :param ev: the evidence.
    :param pool: observable catalogue candidates (fixed columns).
    :param pose_allowed: try the pose-error variance component.
    :param fixed: fixed extra covariance per window (orientation-free diagnosis).
    :param library: candidates beyond the catalogue (``library``), or ``None``.
    :param simplicity: library label -> degree, for ties (``column_step.structured_step``).
    :param excluded: effects that are not candidates (withdrawn by a check before).
    :param th: the diagnosis's knobs (``thresholds``).
    :param excess: (3,) each channel's own excess ε_c² to hold in the noise (channel units²),
        a variance component re-estimated by REML with the other noise terms at every step
        (``model_state.fit_model``) on the channels where it is positive (the start), or ``None``.
    :returns: the selection: its model, its path and, per candidate label, why it was not
        admitted when it could not be told from the model (``"indistinguishable"`` notes).
    """
    n = ev.n_obs
    state = ModelState(excluded=frozenset(excluded))
    X0 = first_order_design(ev.f_m_s2)
    K = np.asarray(np.linalg.lstsq(X0, ev.y.reshape(-1), rcond=None)[0][3:12], dtype=float).reshape(3, 3)
    cap = SlowNoiseCap(ev, th.cap_alpha)
    state.noise, state.fit, K = fit_model(ev, [], False, K, fixed, iterations=2, cap=cap, excess=excess)
    lib = library or []

    def in_pool(st: ModelState) -> list[Candidate]:
        # the catalogue's candidates: not swapped for library terms, not taken out by a check
        return [c for c in pool if c.effect not in st.swapped and c.effect not in st.excluded]

    def n_catalogue(st: ModelState) -> int:
        # the catalogue's candidates still to try, plus the pose error while it is not in
        pose_left = 1 if pose_allowed and not st.pose else 0
        return sum(1 for c in in_pool(st) if not st.holds(c)) + pose_left

    def admit(
        st: ModelState, step: tuple[float, Candidate, float, tuple[NoiseParams, GlsFit, FloatArray]]
    ) -> ModelState:
        dbic, chosen, lr, (noise1, fit1, _K1) = step
        return replace(
            st.copy(), candidates=[*st.candidates, chosen], noise=noise1, fit=fit1,
            steps=[*st.steps, Step(chosen.label, chosen.effect, lr, dbic, len(chosen.names))],
        )  # fmt: skip

    def catalogue(st: ModelState, notes: dict[str, str]) -> ModelState | None:
        alpha = step_alpha(th.false_alarm, n_catalogue(st))
        step = structured_step(ev, in_pool(st), st, scale_matrix_of(st), fixed, alpha, notes, cap=cap, th=th)
        return None if step is None else admit(st, step)

    def beside(st: ModelState) -> list[Candidate]:
        # the library's terms and the catalogue effects searched with them, not taken out by a check
        return [c for c in lib if c.effect not in st.excluded]

    def beyond(st: ModelState, notes: dict[str, str]) -> ModelState | None:
        now = beside(st)
        n_lib = sum(1 for c in now if not st.holds(c))
        step = structured_step(
            ev, now, st, scale_matrix_of(st), fixed, th.library_share * step_alpha(th.false_alarm, n_lib), {},
            prescreen=th.prescreen, simplicity=simplicity, cap=cap, wander_notes=notes, th=th,
        )  # fmt: skip
        return None if step is None else admit(st, step)

    def swap(st: ModelState, notes: dict[str, str]) -> ModelState | None:
        return swap_step(ev, st, scale_matrix_of(st), fixed, beside(st), notes, simplicity, cap, th)

    def pose(st: ModelState, notes: dict[str, str]) -> ModelState | None:
        return pose_step(ev, st, fixed, step_alpha(th.false_alarm, n_catalogue(st)), notes, cap, n, th)

    groups = (catalogue, *((beyond, swap) if lib else ()), *((pose,) if pose_allowed else ()))
    return Selection(extend(Path.start(state), groups, th.max_steps), groups, th.max_steps)
