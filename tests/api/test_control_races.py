"""Control requests either take effect or are refused honestly: a continue sent right after a
pause its agent has not applied yet undoes it (202, the run never holds), and an abort sent
while the run is finishing (every step done, results being stored) is refused with 409 naming
the phase, the run completing as it was. The API and the bench agent share the database as in
the service; the agent is ticked by the test, so each race is hit on purpose."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from bench.records import RunRecord
from station.agent.bench_agent import BenchAgent
from station.runs.live import LiveRun
from tests.support.service_helpers import OP, VIEW, service_settings

pytestmark = pytest.mark.slow


def state_of(client: TestClient, run_id: str) -> str:
    return str(client.get(f"/api/runs/{run_id}", headers=VIEW).json()["state"])


def tick_until(agent: BenchAgent, cond: object, timeout_s: float = 240.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        agent.tick()
        if cond():  # type: ignore[operator]
            return
        time.sleep(0.1)
    raise AssertionError("timed out")


def test_continue_right_after_pause_is_accepted_and_the_run_never_holds(tmp_path: Path) -> None:
    settings = service_settings(tmp_path, agent="external")
    agent = BenchAgent(settings)
    try:
        with TestClient(create_app(settings, start_scheduler=False)) as client:
            r = client.post(
                "/api/runs", json={"unit_serial": "SN-RACE-1", "procedure": "static-12"}, headers=OP
            )
            assert r.status_code == 202, r.text
            run_id = r.json()["id"]
            assert agent.tick() == run_id
            assert state_of(client, run_id) == "running"
            nothing = client.post(f"/api/runs/{run_id}/resume", headers=OP)
            assert nothing.status_code == 409 and "nothing to resume" in nothing.json()["detail"]
            assert client.post(f"/api/runs/{run_id}/pause", headers=OP).status_code == 200
            go = client.post(f"/api/runs/{run_id}/resume", headers=OP)  # before the agent's next poll
            assert go.status_code == 202, go.text
            assert go.json()["action"] == "continue"
            seen: set[str] = set()

            def ended() -> bool:
                seen.add(state_of(client, run_id))
                return agent.runner.current is None

            tick_until(agent, ended)
            assert "paused" not in seen, seen
            assert state_of(client, run_id) == "completed"
    finally:
        agent.close()


def test_an_abort_while_finishing_is_refused_naming_the_phase_and_the_run_completes(tmp_path: Path) -> None:
    settings = service_settings(tmp_path, agent="external")
    agent = BenchAgent(settings)
    finisher = agent.runner.finisher
    assert finisher is not None
    in_finisher, release = threading.Event(), threading.Event()

    def held_finisher(live: LiveRun, record: RunRecord) -> None:
        in_finisher.set()
        release.wait(120)
        finisher(live, record)

    agent.runner.finisher = held_finisher
    try:
        with TestClient(create_app(settings, start_scheduler=False)) as client:
            r = client.post(
                "/api/runs", json={"unit_serial": "SN-RACE-2", "procedure": "static-12"}, headers=OP
            )
            run_id = r.json()["id"]
            tick_until(agent, in_finisher.is_set)
            abort = client.post(f"/api/runs/{run_id}/abort", headers=OP)
            assert abort.status_code == 409, abort.text
            assert "is finishing" in abort.json()["detail"] and "nothing to abort" in abort.json()["detail"]
            pause = client.post(f"/api/runs/{run_id}/pause", headers=OP)
            assert pause.status_code == 409 and "is finishing" in pause.json()["detail"]
            release.set()
            tick_until(agent, lambda: agent.runner.current is None)
            body = client.get(f"/api/runs/{run_id}", headers=VIEW).json()
            assert body["state"] == "completed" and body["outcome"] == "PASS", body
    finally:
        release.set()
        agent.close()
