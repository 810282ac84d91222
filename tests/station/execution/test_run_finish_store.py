"""The end of a run is stored even when the database refuses a write for a while; when it
keeps refusing, the failure names the run, its outcome and the observer instead of leaving
the run silently ``running``."""

from __future__ import annotations

import sqlite3

import pytest

from bench.records import RunRecord, RunStart
from bench.run_observer import NullObserver
from bench.run_state import Outcome, RunState
from station.execution.verdict import RunNotStored, finish_observers

START = RunStart("run-x", "SN-X", "static-12", "bench-a", "/tmp/r.csv", 100.0, 3, 12, 100.0)
RECORD = RunRecord(START, RunState.ERROR, Outcome.ERROR, (), error="recording: disk full")


class Flaky(NullObserver):
    def __init__(self, failures: int) -> None:
        self.failures = failures
        self.calls = 0
        self.stored: RunRecord | None = None

    def on_finish(self, record: RunRecord) -> None:
        self.calls += 1
        if self.calls <= self.failures:
            raise sqlite3.OperationalError("database or disk is full")
        self.stored = record


def test_a_transient_refusal_is_retried_until_the_end_is_stored() -> None:
    db, other = Flaky(failures=2), Flaky(failures=0)
    finish_observers([db, other], RECORD, retry_s=5.0, wait_s=0.01)
    assert db.calls == 3 and db.stored is RECORD and other.stored is RECORD


def test_a_lasting_refusal_names_the_run_the_outcome_and_the_observer() -> None:
    db, other = Flaky(failures=10**6), Flaky(failures=0)
    with pytest.raises(RunNotStored) as info:
        finish_observers([db, other], RECORD, retry_s=0.2, wait_s=0.01)
    text = str(info.value)
    assert "run run-x ended ERROR" in text and "Flaky: OperationalError: database or disk is full" in text
    assert db.calls > 2 and other.stored is RECORD  # the others are still told
