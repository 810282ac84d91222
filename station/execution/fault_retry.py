"""Automatic resume after a fault the bench recovers from (:mod:`bench.sequencer.faults`).

A run ended by such a fault — a table that stalled or reset, a lost link, a DAQ that timed
out, a killed simulator, a full disk — has had its table made safe and its recording closed
at its last durable chunk; it is stored ``interrupted`` with an error beginning
:data:`FAULT_PREFIX` (why), never ``error``. Whoever drives the bench then resumes it from the
window after its last complete one, re-opening the devices, after waits that grow
(:class:`RetryPolicy`: 1, 2, 4, 8, 16, 30 s — a minute in all, more than a 30 s stall), for at
most ``attempts`` tries in a row without a new complete window; a try that records a window
starts the count again. After the last try the run stays ``interrupted``, its error saying
so: an operator resumes it on request (``POST /api/runs/{id}/resume``, ``calbench resume``)
once the bench is fixed.

* ``calbench run`` / ``calbench resume``: :func:`run_resuming`, in the command's process.
* the bench agent: :func:`schedule` stores the next try with the run
  (``Run.auto_resume``), and the agent, while idle, queues the run when it is due
  (:func:`due_resume`); the bench takes no other run meanwhile.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import logging
from collections.abc import Callable, Iterator
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from bench.records import RunRecord
from bench.run_state import RunState
from bench.sequencer.control import RunControl
from db.models import Run
from db.types import utc_now
from station.disk_full import is_disk_full

log = logging.getLogger(__name__)

FAULT_PREFIX = "device fault: "
"""Start of the error of a run interrupted by a fault the bench recovers from."""


@dataclasses.dataclass(frozen=True)
class RetryPolicy:
    """How often and how patiently a run interrupted by a device fault is resumed.

    :param attempts: tries in a row without a new complete window.
    :param first_wait_s: wait before the first try (s); each next one waits twice as long...
    :param max_wait_s: ...up to this (s).
    """

    attempts: int = 6
    first_wait_s: float = 1.0
    max_wait_s: float = 30.0

    def wait_s(self, attempt: int) -> float:
        """Wait before try ``attempt`` (1-based): ``min(first · 2^(attempt−1), max)``."""
        return float(min(self.first_wait_s * 2.0 ** (attempt - 1), self.max_wait_s))


class ResumeFailed(ConnectionError):
    """A run or its resume could not start: the devices did not open (the bench does not answer
    yet). The run was stored or put back ``interrupted`` with the reason; it counts as a try.

    :ivar run_id: the run left ``interrupted`` (``None``: not known to the raiser).
    """

    def __init__(self, message: str, run_id: str | None = None) -> None:
        super().__init__(message)
        self.run_id = run_id


@dataclasses.dataclass(frozen=True)
class NeverStarted:
    """A run whose devices never opened: stored ``interrupted`` with ``error`` (the device and
    the fault), nothing recorded; resuming it starts it as it was requested."""

    run_id: str
    error: str


@contextlib.contextmanager
def disk_full_is_a_try(run_id: str, what: str) -> Iterator[None]:
    """Within it, a write refused because the disk is full (:func:`is_disk_full`: the database
    on a disk still full when the resume claims the run) raises :class:`ResumeFailed` — a try
    of the policy, the run left as it was — instead of ending the tries."""
    try:
        yield
    except ResumeFailed:
        raise
    except Exception as exc:
        if not is_disk_full(exc):
            raise
        first = str(getattr(exc, "orig", None) or exc).splitlines()[0][:200]
        raise ResumeFailed(f"run {run_id}: {what}: the disk is full ({first})", run_id) from exc


def interrupted_by_fault(record: RunRecord | NeverStarted) -> bool:
    """The run stopped on a fault the bench recovers from and may be resumed."""
    if isinstance(record, NeverStarted):
        return True
    return record.state is RunState.INTERRUPTED and (record.error or "").startswith(FAULT_PREFIX)


def next_attempt(previous: object, windows: int) -> int:
    """The number of the next try, from the stored ``Run.auto_resume`` and the run's complete
    windows now: one more than before, or 1 when a window was completed since."""
    if not isinstance(previous, dict) or not isinstance(previous.get("attempt"), int):
        return 1
    before = previous.get("windows")
    if isinstance(before, int) and windows > before:
        return 1
    return int(previous["attempt"]) + 1


def run_resuming(
    first: Callable[[], RunRecord],
    again: Callable[[str], RunRecord],
    control: RunControl,
    say: Callable[[str], None],
    policy: RetryPolicy | None = None,
) -> RunRecord | NeverStarted:
    """``first()``, then ``again(run_id)`` (a resume) after each device fault, as the policy says.

    A start or resume that fails before it records (the devices do not open yet) counts as a
    try; a start that fails so, its run stored ``interrupted`` (:class:`ResumeFailed` with its
    id), is tried again as a resume and, while no try has opened the devices, is answered as
    :class:`NeverStarted`. An abort (Ctrl-C) during a wait ends the tries, the run left
    ``interrupted``.
    """
    policy = policy or RetryPolicy()
    result: RunRecord | NeverStarted
    try:
        result = first()
    except ResumeFailed as exc:
        if exc.run_id is None:
            raise
        result = NeverStarted(exc.run_id, str(exc))
    attempt, windows = 0, _windows(result)
    while interrupted_by_fault(result):
        if _windows(result) > windows:
            attempt, windows = 0, _windows(result)
        attempt += 1
        run_id = result.run_id
        if attempt > policy.attempts:
            say(f"run {run_id}: {policy.attempts} automatic resumes failed; resume it on request")
            return result
        wait = policy.wait_s(attempt)
        say(f"run {run_id}: {result.error}; resuming in {wait:g} s ({attempt}/{policy.attempts})")
        if control.wait_abort(wait):
            return result
        try:
            result = again(run_id)
        except ResumeFailed as exc:
            say(f"run {run_id}: the resume failed: {exc}")
            if isinstance(result, NeverStarted):
                result = NeverStarted(run_id, str(exc))
    return result


def _windows(result: RunRecord | NeverStarted) -> int:
    return 0 if isinstance(result, NeverStarted) else len(result.windows)


def schedule(
    session: Session,
    run_id: str,
    fault: str,
    windows: int,
    policy: RetryPolicy,
    *,
    now: dt.datetime | None = None,
) -> dict[str, Any] | None:
    """Store the next automatic try of the interrupted ``run_id`` (``None``: the tries are spent,
    the run's error says so and it waits for an operator)."""
    run = session.get(Run, run_id, with_for_update=True, populate_existing=True)
    if run is None or run.state is not RunState.INTERRUPTED:
        return None
    attempt = next_attempt(run.auto_resume, windows)
    if attempt > policy.attempts:
        run.auto_resume = {"gave_up": True, "windows": windows, "fault": fault}
        run.error = (
            f"interrupted: {fault}; {policy.attempts} automatic resumes in a row recorded no window: "
            "resume it on request once the bench answers"
        )
        session.flush()
        return None
    not_before = (now or utc_now()) + dt.timedelta(seconds=policy.wait_s(attempt))
    entry = {"attempt": attempt, "not_before": not_before.isoformat(), "windows": windows, "fault": fault}
    run.auto_resume = entry
    session.flush()
    return entry


def schedule_logged(
    sessions: sessionmaker[Session], run_id: str, fault: str, windows: int, policy: RetryPolicy
) -> dict[str, Any] | None:
    """:func:`schedule` in its own transaction, logged; a database that refuses is logged too
    (the run stays ``interrupted``, resumable on request)."""
    try:
        with sessions.begin() as s:
            entry = schedule(s, run_id, fault, windows, policy)
    except Exception as exc:
        if is_disk_full(exc):  # one line: the agent's poll says the disk is full, once a minute
            log.error("run %s: could not schedule its automatic resume: the disk is full", run_id)
        else:
            log.exception("run %s: could not schedule its automatic resume", run_id)
        return None
    if entry is None:
        log.error("run %s: %s; automatic resumes spent, it waits for an operator", run_id, fault)
    else:
        when = entry["not_before"]
        log.warning("run %s: %s; automatic resume %s due at %s", run_id, fault, entry["attempt"], when)
    return entry


def give_up(session: Session, run_id: str, why: str) -> None:
    """No more automatic tries for ``run_id`` (it stays interrupted, its error says ``why``)."""
    run = session.get(Run, run_id, with_for_update=True, populate_existing=True)
    if run is None:
        return
    entry = run.auto_resume
    run.auto_resume = {**(entry if isinstance(entry, dict) else {}), "gave_up": True}
    run.error = f"interrupted: automatic resume refused: {why}"
    session.flush()


def due_resume(session: Session, bench_id: int, *, now: dt.datetime | None = None) -> tuple[str | None, bool]:
    """The bench's interrupted run whose automatic try is due (its id), and whether one is
    pending but not yet due (the bench then waits for it)."""
    now = now or utc_now()
    rows = session.execute(
        sa.select(Run.id, Run.auto_resume).where(Run.bench_id == bench_id, Run.state == RunState.INTERRUPTED)
    ).all()
    waiting = False
    for run_id, entry in sorted(rows):
        if not isinstance(entry, dict) or entry.get("gave_up") or "not_before" not in entry:
            continue
        try:
            due = dt.datetime.fromisoformat(str(entry["not_before"]))
        except ValueError:
            continue
        if (due if due.tzinfo else due.replace(tzinfo=dt.UTC)) <= now:
            return str(run_id), False
        waiting = True
    return None, waiting
