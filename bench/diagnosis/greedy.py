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

The model itself (its state, how a candidate is fitted and scored) is the caller's: a group is
a function from the current state to the next one (``None`` when it has nothing admissible).
Sources: stepwise selection (Efroymson 1960; Miller, "Subset Selection in Regression", 2002,
ch. 3); BIC (Schwarz, Ann. Stat. 6 (1978) 461); the Bonferroni share of a false-alarm budget.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

S = TypeVar("S")
T = TypeVar("T")

Move = Callable[[S], S | None]
"""One group of candidates: the state after its best admissible candidate entered, or ``None``."""


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


def forward(state: S, groups: Sequence[Move[S]], max_steps: int) -> tuple[S, int]:
    """Forward selection (module docstring): (final state, steps taken).

    Each step asks ``groups`` in order and takes the first that returns a new state.
    """
    for step in range(max_steps):
        for group in groups:
            nxt = group(state)
            if nxt is not None:
                state = nxt
                break
        else:
            return state, step
    return state, max_steps


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
