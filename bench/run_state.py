"""The life of a bench run: its states and the verdict it ends with.

:class:`RunState` is the one vocabulary of the bench, the database, the REST service and the
live state::

    QUEUED -> RUNNING <-> PAUSED           (operator)
              RUNNING <-> SUSPENDED        (interlock open, temperature out of band)
              RUNNING -> COMPLETED | FAILED | ERROR | ABORTED   (by the Outcome)
    any live state -> INTERRUPTED          (the process died; set on the next start)
    INTERRUPTED -> QUEUED -> RUNNING       (resumed from the window after the last complete one)

:class:`Outcome` is only set once a run is final: PASS / FAIL (the *unit* is outside its
limits) are verdicts about the unit; ERROR (the *bench* broke: lost link, timeout, fault)
and ABORTED (an operator stopped it) say the run gave no verdict.
:meth:`RunState.finished` maps an outcome to its final state (PASS or none: COMPLETED).
"""

from __future__ import annotations

import enum


class RunState(enum.Enum):
    """Where a run is in its life (see the module docstring for the transitions).

    Live, with an owner process: ``queued`` (waiting for its bench), ``running``, ``paused``
    (operator), ``suspended`` (interlock, temperature). Final: ``completed`` (verdict PASS or
    none), ``failed`` (verdict FAIL: the unit is outside its limits), ``error`` (the bench
    broke), ``aborted`` (operator stop). ``interrupted``: the owner process died; the run can be
    resumed. The values are the stored and the wire names.
    """

    QUEUED = "queued"
    RUNNING = "running"
    PAUSED = "paused"
    SUSPENDED = "suspended"
    INTERRUPTED = "interrupted"
    COMPLETED = "completed"
    FAILED = "failed"
    ERROR = "error"
    ABORTED = "aborted"

    @property
    def is_live(self) -> bool:
        """A process is (or should be) executing the run right now."""
        return self in ACTIVE_STATES

    @property
    def is_final(self) -> bool:
        """A state the run never leaves."""
        return self in FINAL_STATES

    @property
    def holds_bench(self) -> bool:
        """An owner process drives the table (running, paused or suspended)."""
        return self in HOLDING_STATES

    @classmethod
    def finished(cls, outcome: Outcome | None) -> RunState:
        """The final state of a run that ended with ``outcome`` (PASS or none: completed)."""
        return _FINAL_BY_OUTCOME[outcome]


class Outcome(enum.Enum):
    """Verdict of a finished run (openhtf's outcomes)."""

    PASS = "PASS"
    FAIL = "FAIL"
    ERROR = "ERROR"
    ABORTED = "ABORTED"


ACTIVE_STATES = frozenset({RunState.QUEUED, RunState.RUNNING, RunState.PAUSED, RunState.SUSPENDED})
"""States that need a live owner process."""
HOLDING_STATES = frozenset({RunState.RUNNING, RunState.PAUSED, RunState.SUSPENDED})
"""States of a run that holds its bench (an owner process drives the table)."""
RESUMABLE_STATES = frozenset({RunState.INTERRUPTED})
"""States from which a new process may take a run over."""
FINAL_STATES = frozenset({RunState.COMPLETED, RunState.FAILED, RunState.ERROR, RunState.ABORTED})
"""States a run never leaves."""
_FINAL_BY_OUTCOME = {
    None: RunState.COMPLETED,
    Outcome.PASS: RunState.COMPLETED,
    Outcome.FAIL: RunState.FAILED,
    Outcome.ERROR: RunState.ERROR,
    Outcome.ABORTED: RunState.ABORTED,
}
