"""The selection core every diagnosis shares: forward addition under a significance gate and an
information criterion, backward removal of what fails its check.

One rule, whatever the model (static window means, a moving recording's dynamic batch fit,
``calibrate``'s term selection, which calls the moving one):

* **forward** (:func:`forward`): at each step the groups of candidates are asked in order (the
  catalogue, then the library beyond it, then a swap, then a catch-all variance component);
  the first group that has an admissible candidate makes the step. A candidate is admissible
  when its statistic passes its gate (:func:`admits`: a Wald or likelihood-ratio statistic
  above the quantile at the false-alarm probability shared over the candidates of the step,
  :func:`step_alpha`) **and** its BIC change is negative; among a group's admissible
  candidates the one of lowest BIC change enters (:func:`best`). Selection stops when no
  group has one, or after ``max_steps`` steps.
* **backward** (:func:`backward`): while some effect of the model fails its check (its Wald
  statistic below the gate it passed to enter, or no out-of-sample gain), the worst offender
  is removed and the model refitted.
* **resume** (:func:`resume`): the forward selection keeps its path (:class:`Path`: the state
  after each step, and what each step's groups noted). When a check takes an effect out of the
  pool, the selection goes back to the state before that effect first entered, takes it out of
  the candidates there and continues forward: the steps before its admission stand (it was
  tried at each of them and lost), those after it are made again without it. The selection
  runs once; nothing before the effect's admission is fitted again.

The model itself (its state, how a candidate is fitted and scored) is the caller's: a group is
a function from the current state to the next one (``None`` when it has nothing admissible).
Sources: stepwise selection (Efroymson 1960; Miller, "Subset Selection in Regression", 2002,
ch. 3); BIC (Schwarz, Ann. Stat. 6 (1978) 461); the Bonferroni share of a false-alarm budget.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

S = TypeVar("S")
T = TypeVar("T")

Move = Callable[[S], S | None]
"""One group of candidates: the state after its best admissible candidate entered, or ``None``."""

NotedMove = Callable[[S, dict[str, str]], S | None]
"""A group that also says why it set candidates aside (label -> sentence, written into the
dict it is given). It must not change the state it is given (the path keeps it)."""


@dataclass(frozen=True)
class Trial(Generic[T]):
    """One candidate scored against the current model.

    :param item: the candidate (or whatever the caller needs back: its fit, its model).
    :param statistic: its Wald or likelihood-ratio statistic (χ²-like, ≥ 0).
    :param gate: the statistic it must exceed (the quantile at the step's false alarm).
    :param delta_bic: BIC of the extended model minus the current one.
    """

    item: T
    statistic: float
    gate: float
    delta_bic: float


def step_alpha(false_alarm: float, n_candidates: int) -> float:
    """False-alarm probability of one candidate: the step's budget shared over those tried
    (Bonferroni), α = false_alarm / max(N, 1)."""
    return false_alarm / max(n_candidates, 1)


def admits(trial: Trial[T]) -> bool:
    """The admission rule: statistic above its gate and BIC lowered."""
    return trial.statistic > trial.gate and trial.delta_bic < 0


def best(trials: Sequence[Trial[T]]) -> Trial[T] | None:
    """The admissible trial of lowest BIC change (the first of equals), or ``None``."""
    ok = [t for t in trials if admits(t)]
    return min(ok, key=lambda t: t.delta_bic) if ok else None


@dataclass(frozen=True)
class Path(Generic[S]):
    """A forward selection's states: ``states[0]`` the start, ``states[k]`` after step k;
    ``notes[k]`` what the groups noted when asked at ``states[k]`` (for the last state, the
    step that found nothing; empty when the path stopped at ``max_steps``)."""

    states: tuple[S, ...]
    notes: tuple[Mapping[str, str], ...]

    @classmethod
    def start(cls, state: S) -> Path[S]:
        """The path of no steps from ``state``."""
        return cls((state,), ({},))

    @property
    def last(self) -> S:
        """The state at the end of the path."""
        return self.states[-1]

    @property
    def steps(self) -> int:
        """Steps taken."""
        return len(self.states) - 1

    @property
    def noted(self) -> dict[str, str]:
        """Every step's notes, in order (a label's later note replaces an earlier one)."""
        out: dict[str, str] = {}
        for n in self.notes:
            out.update(n)
        return out


def extend(path: Path[S], groups: Sequence[NotedMove[S]], max_steps: int) -> Path[S]:
    """Forward selection (module docstring) from the end of ``path``, until no group has a
    candidate or the path has ``max_steps`` steps. The last state's notes are those of the
    groups asked again from it."""
    states, notes = list(path.states), list(path.notes[:-1])
    while len(states) <= max_steps:
        noted: dict[str, str] = {}
        notes.append(noted)
        for group in groups:
            nxt = group(states[-1], noted)
            if nxt is not None:
                states.append(nxt)
                break
        else:
            return Path(tuple(states), tuple(notes))
    notes.append({})
    return Path(tuple(states), tuple(notes))


def forward(state: S, groups: Sequence[Move[S]], max_steps: int) -> tuple[S, int]:
    """Forward selection (module docstring): (final state, steps taken).

    Each step asks ``groups`` in order and takes the first that returns a new state.
    """
    noted = [lambda s, _n, g=g: g(s) for g in groups]
    path = extend(Path.start(state), noted, max_steps)
    return path.last, path.steps


def resume(
    path: Path[S],
    groups: Sequence[NotedMove[S]],
    max_steps: int,
    holds: Callable[[S], bool],
    without: Callable[[S], S],
) -> Path[S]:
    """Resume (module docstring): back to the state before the first one for which ``holds``
    is true (the step that admitted what is taken out), ``without`` applied to it (the effect
    out of the candidates), then forward from there. A path none of whose states ``holds``
    only gets ``without`` at its end, and goes on."""
    k = next((i for i, s in enumerate(path.states) if holds(s)), len(path.states))
    back = max(k - 1, 0) if k < len(path.states) else len(path.states) - 1
    states = (*path.states[:back], without(path.states[back]))
    return extend(Path(states, (*path.notes[:back], {})), groups, max_steps)


def backward(state: S, worst: Callable[[S], tuple[str, S] | None]) -> tuple[S, list[str]]:
    """Backward removal (module docstring): (final state, labels removed in order).

    ``worst`` returns the worst offender's label and the state without it, or ``None`` when
    every effect passes its check.
    """
    removed: list[str] = []
    while (out := worst(state)) is not None:
        label, state = out
        removed.append(label)
    return state, removed
