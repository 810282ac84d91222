"""How a run's acquisition ended: its outcome, the error line, whether the bench may resume it.

An operator abort ends as ABORTED (``aborted at <where>: <reason>``); a driver fault, a
deadline, a DAQ stall, a recording write refused, an observer's failure or a rejected value
(:data:`RUN_FAULTS`) as ERROR naming where it happened (``<where>: <type>: <message>``). A
fault a lab's bench recovers from (:func:`bench.sequencer.faults.resumable_fault`) — a device
that stops answering (stall, reset), a lost link, a garbled reply, a recording or database
write refused because the disk is full — marks the ERROR *resumable*: the caller leaves the
run interrupted and resumes it from its last durable window
(:mod:`station.execution.fault_retry`); a fault the device reports itself (an axis fault, a
Modbus exception), a limit, a rejected window or another database refusal does not. In every
case, and on success, the table is then made safe
(:func:`bench.sequencer.safety.make_safe`); what failed there is added to the error line and
ends a run whose every step was done as ERROR, resumable only when every fault met making it
safe is one the bench recovers from. :class:`Acquisition` is what the sequencer leaves behind.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from bench.records import DwellChoice, GapRecord, WindowRecord
from bench.run_state import Outcome
from bench.sequencer.control import AbortRequested
from bench.sequencer.faults import resumable_fault
from bench.sequencer.observers import ObserverError
from drivers.errors import DriverError

RUN_FAULTS: tuple[type[Exception], ...] = (DriverError, TimeoutError, OSError, ObserverError, ValueError)
"""What ends a run as ERROR; anything else propagates out of the run, after the table is made safe."""


@dataclass(frozen=True)
class Ending:
    """How the steps ended.

    :param outcome: ``None`` when every step completed, else ERROR or ABORTED.
    :param error: what went wrong and where, else ``None``.
    :param resumable: the ERROR was a fault the bench recovers from.
    """

    outcome: Outcome | None = None
    error: str | None = None
    resumable: bool = False

    @classmethod
    def aborted(cls, where: str, exc: AbortRequested) -> Ending:
        """The operator aborted the run at ``where``."""
        return cls(Outcome.ABORTED, f"aborted at {where}: {exc}")

    @classmethod
    def fault(cls, where: str, exc: Exception) -> Ending:
        """``exc`` (one of :data:`RUN_FAULTS`) ended the run at ``where``."""
        return cls(Outcome.ERROR, f"{where}: {type(exc).__name__}: {exc}", resumable_fault(exc))

    def after_safe_state(self, problems: Sequence[str], faults: Sequence[BaseException]) -> Ending:
        """The end once the table was made safe.

        :param problems: what failed making it safe (one line each); none: unchanged.
        :param faults: the exceptions met making it safe (the table, the DAQ's stop, the
            recording's close); a run whose every step was done resumes only if they all are
            faults the bench recovers from.
        """
        if not problems:
            return self
        error = "; ".join([self.error or "completed", *problems])
        resumable = self.resumable
        if self.outcome is None:  # every step done, the safe state unconfirmed: a lost link resumes
            resumable = bool(faults) and all(resumable_fault(e) for e in faults)
        return Ending(self.outcome or Outcome.ERROR, error, resumable)


@dataclass(frozen=True)
class Acquisition:
    """What the sequencer leaves behind.

    :param outcome: ``None`` when every step completed, else ERROR or ABORTED.
    :param error: what went wrong and where (ERROR, ABORTED), else ``None``.
    :param windows: every completed window (also those from before a resume).
    :param dwell: the dwell choice used.
    :param n_samples: rows in the recording.
    :param gaps: every sample gap met, in order (also those from before a resume).
    :param resumable: the ERROR was a fault the bench recovers from
        (:func:`bench.sequencer.faults.resumable_fault`): the run may continue from its last
        durable window.
    """

    outcome: Outcome | None
    error: str | None
    windows: tuple[WindowRecord, ...]
    dwell: DwellChoice | None
    n_samples: int
    gaps: tuple[GapRecord, ...] = ()
    resumable: bool = False
