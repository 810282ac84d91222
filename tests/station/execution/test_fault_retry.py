"""The automatic resume policy after a device fault: which faults qualify, the waits, the count
of tries in a row without a new window, and the agent's schedule in the database."""

from __future__ import annotations

import datetime as dt
import errno
from pathlib import Path

import pytest

from bench.records import RunRecord, RunStart, WindowKind, WindowRecord
from bench.run_state import RunState
from bench.sequencer.control import RunControl
from bench.sequencer.faults import resumable_fault
from bench.sequencer.observers import ObserverError
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Run
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from drivers.errors import DeviceError, DeviceTimeout, LimitError, LinkLost, ProtocolError
from station.execution.fault_retry import (
    FAULT_PREFIX,
    NeverStarted,
    ResumeFailed,
    RetryPolicy,
    due_resume,
    next_attempt,
    run_resuming,
    schedule,
)

START = RunStart("run-1", "SN-1", "static-12", "vm", "/x.csv", 100.0, 3, 12, 100.0)
T0 = dt.datetime(2026, 11, 27, 7, 0, tzinfo=dt.UTC)


def test_faults_the_bench_recovers_from_are_resumable_and_no_others() -> None:
    assert resumable_fault(DeviceTimeout("no reply"))
    assert resumable_fault(LinkLost("reset by peer"))
    assert resumable_fault(ProtocolError("garbled", b"\x00"))
    assert resumable_fault(OSError(errno.ENOSPC, "No space left on device"))
    assert not resumable_fault(DeviceError("axis 2: following error", code=203))
    assert not resumable_fault(LimitError("rate"))
    assert not resumable_fault(ValueError("bad"))
    assert not resumable_fault(ObserverError("database refused"))


def test_the_waits_double_up_to_the_cap_and_outlast_a_30_s_stall() -> None:
    policy = RetryPolicy()
    waits = [policy.wait_s(i) for i in range(1, policy.attempts + 1)]
    assert waits == [1.0, 2.0, 4.0, 8.0, 16.0, 30.0]
    assert sum(waits) > 30.0


def test_a_new_window_starts_the_count_again() -> None:
    assert next_attempt(None, 3) == 1
    assert next_attempt({"attempt": 2, "windows": 3}, 3) == 3
    assert next_attempt({"attempt": 5, "windows": 3}, 4) == 1


def record(state: RunState, n_windows: int, error: str | None = None) -> RunRecord:
    w = WindowRecord(0, "w", WindowKind.STATIC, 0.0, 1.0, 100, (0.0,) * 3, (0.0,) * 3, 20.0, 0)
    return RunRecord(START, state, None, tuple(w for _ in range(n_windows)), error=error)


def test_run_resuming_tries_until_the_run_ends_and_gives_up_after_the_attempts() -> None:
    fault = FAULT_PREFIX + "DeviceTimeout: no reply"
    calls: list[str] = []
    results = [
        ResumeFailed("devices did not open"),
        record(RunState.INTERRUPTED, 2, fault),
        record(RunState.COMPLETED, 12),
    ]

    def again(run_id: str) -> RunRecord:
        calls.append(run_id)
        out = results.pop(0)
        if isinstance(out, Exception):
            raise out
        return out

    said: list[str] = []
    fast = RetryPolicy(attempts=3, first_wait_s=0.001, max_wait_s=0.002)
    done = run_resuming(
        lambda: record(RunState.INTERRUPTED, 1, fault), again, RunControl(), said.append, fast
    )
    assert isinstance(done, RunRecord) and done.state is RunState.COMPLETED and calls == ["run-1"] * 3
    tries = [m[m.rindex("(") :] for m in said if "resuming in" in m]
    assert tries == ["(1/3)", "(2/3)", "(1/3)"]  # the window gained on the second try reset the count
    spent = run_resuming(
        lambda: record(RunState.INTERRUPTED, 1, fault),
        lambda r: record(RunState.INTERRUPTED, 1, fault),
        RunControl(),
        said.append,
        fast,
    )
    assert isinstance(spent, RunRecord) and spent.state is RunState.INTERRUPTED
    assert "3 automatic resumes failed" in said[-1]


def test_an_abort_during_the_wait_ends_the_tries() -> None:
    control = RunControl()
    control.abort("Ctrl-C")
    fault = FAULT_PREFIX + "LinkLost"
    out = run_resuming(lambda: record(RunState.INTERRUPTED, 1, fault), pytest.fail, control, lambda s: None)
    assert isinstance(out, RunRecord) and out.state is RunState.INTERRUPTED


def test_a_start_whose_devices_do_not_open_is_resumed_and_answered_never_started_until_one_opens() -> None:
    """The start raises ResumeFailed with the stored run's id: every try is a resume of that run;
    while none opens the devices the answer is NeverStarted with the last try's error."""
    fast = RetryPolicy(attempts=3, first_wait_s=0.001, max_wait_s=0.002)
    said: list[str] = []

    def start() -> RunRecord:
        raise ResumeFailed(FAULT_PREFIX + "the table at serial:///dev/ttyS0 did not answer", "run-1")

    tries: list[str] = []

    def still_down(run_id: str) -> RunRecord:
        tries.append(run_id)
        raise ResumeFailed(f"{FAULT_PREFIX}try {len(tries)}: the table did not answer", run_id)

    out = run_resuming(start, still_down, RunControl(), said.append, fast)
    assert out == NeverStarted("run-1", f"{FAULT_PREFIX}try 3: the table did not answer")
    assert tries == ["run-1"] * 3 and "3 automatic resumes failed" in said[-1]
    assert "serial:///dev/ttyS0" in said[0]
    down = [ResumeFailed(FAULT_PREFIX + "still down", "run-1")]

    def back(run_id: str) -> RunRecord:
        if down:
            raise down.pop()
        return record(RunState.COMPLETED, 12)

    done = run_resuming(start, back, RunControl(), said.append, fast)
    assert isinstance(done, RunRecord) and done.state is RunState.COMPLETED


def test_a_start_failure_without_a_stored_run_is_raised() -> None:
    def start() -> RunRecord:
        raise ResumeFailed("the devices did not open")

    with pytest.raises(ResumeFailed):
        run_resuming(start, pytest.fail, RunControl(), lambda s: None)


def test_the_schedule_is_due_after_its_wait_and_holds_the_bench_meanwhile(tmp_path: Path) -> None:
    engine = open_database(f"sqlite:///{tmp_path / 'c.db'}")
    sessions = make_session_factory(engine)
    policy = RetryPolicy(attempts=2)
    try:
        with sessions.begin() as s:
            bench = get_or_create_bench(s, "vm").id
            unit = get_or_create_unit(s, "SN-1").id
            create_run(
                s,
                "run-1",
                unit,
                "static-12",
                bench_id=bench,
                params={},
                recording_path="/x.csv",
                state=RunState.INTERRUPTED,
            )
        with sessions.begin() as s:
            assert schedule(s, "run-1", "device fault: x", 3, policy, now=T0) is not None
            assert due_resume(s, bench, now=T0) == (None, True)
            assert due_resume(s, bench, now=T0 + dt.timedelta(seconds=1.5)) == ("run-1", False)
            assert schedule(s, "run-1", "device fault: x", 3, policy, now=T0)["attempt"] == 2  # type: ignore[index]
            assert schedule(s, "run-1", "device fault: x", 3, policy, now=T0) is None  # spent
            run = s.get(Run, "run-1")
            assert run is not None and run.auto_resume["gave_up"]
            assert "2 automatic resumes in a row recorded no window" in (run.error or "")
            assert due_resume(s, bench, now=T0 + dt.timedelta(hours=1)) == (None, False)
    finally:
        engine.dispose()
