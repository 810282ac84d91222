"""Pause, continue and resume over REST, and a shutdown that leaves the run resumable.

Through the real app (TestClient, simulated bench): a live run is paused and continued to
its certificate; a shutdown of the app (its lifespan's end) stores the live run
``interrupted`` rather than aborted; the next app on the same database resumes it from its
next window with live events, and the certificate is issued as for a fresh run.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from tests.support.service_helpers import OP, VIEW, service_settings, signed_link, wait_final
from tests.support.sse import sse_events

pytestmark = [pytest.mark.slow, pytest.mark.timeout(400)]  # whole simulated runs through the service


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    app = create_app(service_settings(tmp_path_factory.mktemp("resume")), start_scheduler=False)
    with TestClient(app) as c:
        yield c


def wait_run(
    client: TestClient, run_id: str, cond: Any, what: str, timeout_s: float = 240.0
) -> dict[str, Any]:
    """Poll ``GET /api/runs/{id}`` until ``cond(run)``; a generous deadline, not a measurement."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        run = client.get(f"/api/runs/{run_id}", headers=VIEW).json()
        if cond(run):
            return run
        time.sleep(0.1)
    raise AssertionError(f"run {run_id}: waited {timeout_s} s for {what}: {run}")


def stream(client: TestClient, run_id: str) -> list[tuple[str, dict[str, Any]]]:
    """Every event of the run's stream until it ends."""
    with client.stream("GET", signed_link(client, f"/api/runs/{run_id}/events")) as s:
        return list(sse_events(s.iter_lines()))


def started(client: TestClient, serial: str) -> str:
    r = client.post("/api/runs", json={"unit_serial": serial, "procedure": "static-12"}, headers=OP)
    assert r.status_code == 202, r.text
    return str(r.json()["id"])


def test_pause_holds_the_run_and_resume_continues_it(client: TestClient) -> None:
    run_id = started(client, "SN-PAUSE")
    wait_run(client, run_id, lambda r: (r.get("last_complete_window") or -1) >= 1, "two windows")
    r = client.post(f"/api/runs/{run_id}/pause", headers=OP)
    assert r.status_code == 200 and r.json() == {
        "id": run_id,
        "action": "pause",
        "state": "paused",
        "resumed_from_window": None,
    }
    held = wait_run(client, run_id, lambda r: r["state"] == "paused", "the pause")
    # While it holds the bench, a second start waits in the queue (and is withdrawn here).
    second = client.post("/api/runs", json={"unit_serial": "SN-X", "procedure": "static-12"}, headers=OP)
    assert second.status_code == 202
    assert client.get(f"/api/runs/{second.json()['id']}", headers=VIEW).json()["state"] == "queued"
    assert client.post(f"/api/runs/{second.json()['id']}/abort", headers=OP).status_code == 200
    r = client.post(f"/api/runs/{run_id}/resume", headers=OP)
    assert r.status_code == 202 and r.json()["action"] == "continue"
    body = wait_final(client, run_id)
    assert body["state"] == "completed", body["error"]
    assert body["certificate_number"] and body["last_complete_window"] == 11
    assert held["last_complete_window"] <= 11


def test_refusals_name_the_reason(client: TestClient) -> None:
    for action in ("pause", "resume"):
        assert client.post(f"/api/runs/no-such-run/{action}", headers=OP).status_code == 404
        assert client.post(f"/api/runs/no-such-run/{action}", headers=VIEW).status_code == 403
        assert client.post(f"/api/runs/no-such-run/{action}").status_code == 401
    run_id = started(client, "SN-REFUSE")
    body = wait_final(client, run_id)
    assert body["state"] == "completed"
    r = client.post(f"/api/runs/{run_id}/resume", headers=OP)
    assert r.status_code == 409 and "only an interrupted run can be resumed" in r.json()["detail"]
    r = client.post(f"/api/runs/{run_id}/pause", headers=OP)
    assert r.status_code == 409 and "is completed" in r.json()["detail"]


def test_shutdown_leaves_the_run_interrupted_and_resume_finishes_it(tmp_path: Path) -> None:
    settings = service_settings(tmp_path)
    with TestClient(create_app(settings, start_scheduler=False)) as first:
        run_id = started(first, "SN-RESTART")
        before = wait_run(
            first, run_id, lambda r: (r.get("last_complete_window") or -1) >= 2, "three windows"
        )
    # The app has shut down with the run live: it is stored interrupted, not aborted.
    with TestClient(create_app(settings, start_scheduler=False)) as second:
        run = second.get(f"/api/runs/{run_id}", headers=VIEW).json()
        assert run["state"] == "interrupted", run
        assert "shut down" in run["error"] and run["outcome"] is None
        done = run["last_complete_window"]
        assert done >= before["last_complete_window"]
        r = second.post(f"/api/runs/{run_id}/resume", headers=OP)
        assert r.status_code == 202, r.text
        assert r.json() == {
            "id": run_id,
            "action": "resume",
            "state": "queued",
            "resumed_from_window": done + 1,
        }
        events = stream(second, run_id)
        windows = [d["index"] for e, d in events if e == "window"]
        assert windows and windows[0] >= done + 1 and windows[-1] == 11
        assert windows == sorted(windows)
        assert any(e == "progress" for e, _ in events)
        assert events[-1][0] == "finished" and events[-1][1]["state"] == "completed"
        assert events[-1][1]["certificate_number"]
        body = wait_final(second, run_id)
        assert body["state"] == "completed"
        assert body["certificate_number"] == events[-1][1]["certificate_number"]
        assert body["last_complete_window"] == 11
        cert = second.get(f"/api/runs/{run_id}/certificate", headers=VIEW)
        assert cert.status_code == 200
        # The certificate names the interruption and the resume as the audit trail stored them.
        audit = second.get(f"/api/runs/{run_id}/audit", headers=VIEW).json()
        stopped = next(a for a in audit if a["state"] == "interrupted")
        resumed = next(a for a in audit if a["action"] == "resume")
        assert resumed["window_index"] == done + 1 and stopped["actor"] == "system"
        deviations = cert.json()["content"]["method"]["deviations"]
        assert any(d.startswith("interrupted at ") and "shut down" in d for d in deviations), deviations
        assert any(f"resumed at window {done + 1} on request of" in d for d in deviations), deviations
        integrity = cert.json()["content"]["conditions"]["sample_integrity"]
        assert "interrupted and continued 1 time" in integrity and "every sample" not in integrity
        # Resumed once; nothing else to resume.
        assert second.post(f"/api/runs/{run_id}/resume", headers=OP).status_code == 409
