"""How a run the runner's worker executed ends in the database, whatever ended it.

The worker (:meth:`station.runs.runner.BenchRunner._work`) hands every ending here:

* a run a device fault interrupted (table safe, recording closed) gets its next automatic
  resume stored (:func:`schedule_resume`, the retry policy of
  :mod:`station.execution.fault_retry`);
* a run whose verdict was left live for the finisher gets its final state stored
  (:func:`store_final_state`), with the finisher's error, if it failed, as its certificate note;
* a run that failed in the service before it recorded is stored ``error``
  (:func:`store_error`); a resume that failed before it continued is put back ``interrupted``
  (:func:`release_claim`) and counted as a try of the retry policy, or ends the automatic tries
  (:func:`after_failed_resume`);
* every run's last event (:func:`terminal_event`) is stored as ``Run.final_event``
  (:func:`store_final_event`), with which API processes end their event streams.

Each store is its own transaction; one that fails is logged, never raised: the worker must end
and free the bench.
"""

from __future__ import annotations

import logging

from sqlalchemy.orm import Session, sessionmaker

from bench.records import RunRecord
from bench.run_state import RunState
from bench.sequencer.faults import resumable_fault
from db.models import RunState as DbRunState
from db.observer import finish_record
from db.repo.recovery import mark_run_interrupted
from db.repo.runs import finish_run, set_certificate_error, set_final_event
from station.execution import fault_retry
from station.execution.fault_retry import FAULT_PREFIX, RetryPolicy
from station.runs.live import LiveRun

log = logging.getLogger(__name__)

HIDDEN_EXTRA = ("dwell_s", "claimed", "procedure_kw")
"""The worker's own keys of ``LiveRun.extra``, left out of the terminal event."""


def final_state(record: RunRecord | None) -> RunState:
    """The record's final state (a completed fit no limits judged has no outcome); ERROR when
    there is no record or it is not final."""
    if record is None or not record.state.is_final:
        return RunState.ERROR
    return record.state


def terminal_event(live: LiveRun, record: RunRecord | None) -> dict[str, object]:
    """The run's last event: state, outcome, conformity note, error and what the finisher added
    to ``live.extra`` (certificate number, drift result, analysis time)."""
    return {
        "state": live.state.value,
        "outcome": record.outcome.value if record and record.outcome else None,
        "conformity_note": record.conformity_note if record and record.conformity_note else None,
        "error": live.error,
        **{k: v for k, v in live.extra.items() if k not in HIDDEN_EXTRA},
    }


def schedule_resume(
    sessions: sessionmaker[Session], live: LiveRun, fault: str, windows: int, retry: RetryPolicy
) -> None:
    """Store the run's next automatic resume (the agent queues it when due)."""
    live.extra["auto_resume"] = fault_retry.schedule_logged(sessions, live.id, fault, windows, retry)


def store_final_state(sessions: sessionmaker[Session], live: LiveRun, record: RunRecord) -> None:
    """Store the final state of a run whose verdict was left live for the finisher (which
    normally stores it with the certificate); a finisher that failed leaves its error."""
    if not record.state.is_final:
        return
    try:
        with sessions.begin() as s:
            if finish_record(s, record) and live.error and live.error != record.error:
                set_certificate_error(s, live.id, f"results not stored: {live.error}")
    except Exception:
        log.exception("run %s: could not store its final state", live.id)


def store_error(sessions: sessionmaker[Session], live: LiveRun) -> None:
    """Store the run ``error`` with ``live.error`` (a claimed run must not stay live without an
    owner at work)."""
    try:
        with sessions.begin() as s:
            finish_run(s, live.id, DbRunState.ERROR, outcome="ERROR", error=live.error)
    except Exception:
        log.exception("run %s: could not store its error", live.id)


def store_final_event(sessions: sessionmaker[Session], live: LiveRun, finished: dict[str, object]) -> None:
    """The run's last event (``Run.final_event``: state, outcome, error, certificate number or
    drift result): API processes end their event streams with it (the results and
    certificate are stored by then)."""
    try:
        with sessions.begin() as s:
            set_final_event(s, live.id, finished)
    except Exception:
        log.exception("run %s: could not store its final event", live.id)


def release_claim(sessions: sessionmaker[Session], live: LiveRun) -> bool:
    """Put a claimed run whose resume failed before it continued back ``interrupted``
    (resumable again); False if that could not be stored."""
    try:
        with sessions.begin() as s:
            return mark_run_interrupted(s, live.id, f"resume failed: {live.error}")
    except Exception:
        log.exception("run %s: could not mark it interrupted again", live.id)
        return False


def after_failed_resume(
    sessions: sessionmaker[Session], live: LiveRun, exc: Exception, retry: RetryPolicy
) -> None:
    """A resume that failed before it recorded is a try of the retry policy: after a fault
    the bench recovers from (a full disk, a link) the next try is scheduled after its wait,
    counted; after any other error the automatic tries end, the run's error saying why (an
    operator resumes it on request). Never the same due try again at the next poll."""
    claimed = live.extra.get("claimed")
    windows = claimed.point.next_window_index if claimed else 0
    if resumable_fault(exc):
        schedule_resume(sessions, live, f"{FAULT_PREFIX}resume failed: {live.error}", windows, retry)
        return
    try:
        with sessions.begin() as s:
            fault_retry.give_up(s, live.id, f"the resume failed: {live.error}")
    except Exception:
        log.exception("run %s: could not end its automatic resumes", live.id)
