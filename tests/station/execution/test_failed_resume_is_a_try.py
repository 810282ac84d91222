"""A resume the agent starts that fails before it records is one try of the retry policy:
after a fault the bench recovers from (a full disk) the tries go on, each after its wait, and
end after the policy's number; after any other error they end at once, saying why. Never the
same due try again at every poll."""

from __future__ import annotations

import errno
import itertools
import time
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

import station.execution.session as session_mod
import station.runs.resume as resume_mod
from api.main import create_app
from db.models import Run
from drivers.errors import LinkLost
from station.execution.fault_retry import RetryPolicy
from tests.support.service_helpers import OP, service_settings

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

POLICY = RetryPolicy(attempts=3, first_wait_s=0.2, max_wait_s=0.4)


@pytest.mark.parametrize(
    ("failure", "tries"),
    [
        (OSError(errno.ENOSPC, "No space left on device"), POLICY.attempts),
        (RuntimeError("bench file changed"), 1),
    ],
)
def test_a_failed_resume_counts_as_a_try(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, failure: Exception, tries: int
) -> None:
    def bench_down(*args: Any, **kwargs: Any) -> Any:  # the run's start: a fault before it records
        raise LinkLost("DAQ modbus-tcp://127.0.0.1:1 unit 1: connection refused or unreachable")

    calls: list[float] = []

    def resume_fails(*args: Any, **kwargs: Any) -> Any:
        calls.append(time.monotonic())
        raise failure

    monkeypatch.setattr(session_mod, "open_devices", bench_down)
    monkeypatch.setattr(resume_mod, "continue_run", resume_fails)
    with TestClient(create_app(service_settings(tmp_path), start_scheduler=False)) as client:
        services = client.app.state.services  # type: ignore[attr-defined]
        services.agent.runner.retry = POLICY
        r = client.post("/api/runs", json={"unit_serial": "SN-TRY", "procedure": "static-12"}, headers=OP)
        assert r.status_code == 202, r.text
        run_id = r.json()["id"]
        deadline = time.monotonic() + 60.0
        entry: Any = None
        while time.monotonic() < deadline:
            with services.sessions.begin() as s:
                run = s.get(Run, run_id)
                entry = run.auto_resume if run is not None else None
                state, error = (run.state.value, run.error) if run is not None else ("?", "")
            if isinstance(entry, dict) and entry.get("gave_up") and state == "interrupted":
                break
            time.sleep(0.1)
        time.sleep(1.0)  # no try after the last one
    assert isinstance(entry, dict) and entry.get("gave_up"), (entry, len(calls))
    assert len(calls) == tries, calls
    waits = [b - a for a, b in itertools.pairwise(calls)]
    assert all(w >= POLICY.first_wait_s * 0.9 for w in waits), waits  # each try after its wait
    assert state == "interrupted" and error
