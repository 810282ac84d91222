"""A diagnosis as an ordered tuple of named stages.

A stage is a function ``stage(evidence, state, thresholds) -> (state, notes)`` with one rule,
written in its docstring: it reads the evidence and what the stages before it decided (the
state, a frozen record), decides one thing, and says why it set something aside (``notes``:
label -> sentence, kept beside the state and reported). A :class:`Pipeline` is the tuple of
stages for one kind of recording (``stages`` for static, hand-held and orientation-free window
means; ``moving_stages``, put in order by ``dynamic``, for moving recordings); kinds whose
physics is the same share the same stage functions, and every selection stage calls the one
selection core (``greedy``).

:meth:`Pipeline.run` keeps the trace: each stage's name and its notes, in order, so a
recording can be followed through the stages (docs/diagnose.md, "Following one recording
through the stages").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Generic, Protocol, Self, TypeVar

from bench.diagnosis.thresholds import THRESHOLDS, Thresholds

Notes = Mapping[str, str]
"""label -> why something was set aside (or a remark on what a stage did)."""


class NotedState(Protocol):
    """A pipeline's state: a frozen dataclass with the notes so far (label -> sentence)."""

    @property
    def notes(self) -> Mapping[str, str]: ...

    def noted(self, notes: Notes) -> Self:
        """The state with ``notes`` added (a label's later note replaces an earlier one)."""
        ...


E = TypeVar("E")
S = TypeVar("S", bound=NotedState)
Stage = Callable[[E, S, Thresholds], tuple[S, Notes]]


@dataclass(frozen=True)
class Trace:
    """What one run did: each stage's name and notes, in order."""

    stages: tuple[tuple[str, Notes], ...]

    @property
    def names(self) -> tuple[str, ...]:
        """The stages' names, in order."""
        return tuple(n for n, _ in self.stages)


@dataclass(frozen=True)
class Pipeline(Generic[E, S]):
    """One kind of recording's diagnosis: its name and its stages, in order."""

    name: str
    stages: tuple[Stage[E, S], ...]

    def run(
        self,
        evidence: E,
        state: S,
        thresholds: Thresholds = THRESHOLDS,
        *,
        until: Callable[[S], bool] | None = None,
    ) -> tuple[S, Trace]:
        """Every stage in order; each one's notes are added to the state it returns. ``until``:
        stop after the first stage whose state it holds for (the trace then ends there)."""
        trace: list[tuple[str, Notes]] = []
        for stage in self.stages:
            state, notes = stage(evidence, state, thresholds)
            state = state.noted(notes)
            trace.append((stage.__name__, dict(notes)))
            if until is not None and until(state):
                break
        return state, Trace(tuple(trace))

    @property
    def stage_names(self) -> tuple[str, ...]:
        """The stages' names, in order."""
        return tuple(s.__name__ for s in self.stages)
