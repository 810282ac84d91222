"""The audit trail of a run through the real app (simulated bench): every request names the
operator of its token, every state change the agent, each with its UTC time, in
``GET /api/runs/{id}/audit`` and ``GET /api/runs/{id}``."""

from __future__ import annotations

import datetime as dt
import time
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from tests.support.service_helpers import VIEW, service_settings, wait_final, wait_state

pytestmark = [pytest.mark.slow, pytest.mark.timeout(400)]  # whole simulated runs through the service

ADA_SECRET = "ada-operator-secret-1"
ADMIN_SECRET = "admin-secret-for-audit"
ADA = {"Authorization": f"Bearer {ADA_SECRET}"}
ADMIN = {"Authorization": f"Bearer {ADMIN_SECRET}"}


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    settings = service_settings(tmp_path_factory.mktemp("audit"))
    tokens = [*settings.tokens, f"operator:{ADA_SECRET}:Ada Lovelace", f"admin:{ADMIN_SECRET}:Lab Admin"]
    app = create_app(settings.model_copy(update={"tokens": tokens}), start_scheduler=False)
    with TestClient(app) as c:
        yield c


@pytest.fixture(scope="module")
def grace(client: TestClient) -> dict[str, str]:
    """A database token made over /api/tokens for Grace Hopper."""
    r = client.post("/api/tokens", json={"role": "operator", "operator": "Grace Hopper"}, headers=ADMIN)
    assert r.status_code == 201, r.text
    assert r.json()["operator"] == "Grace Hopper"
    return {"Authorization": f"Bearer {r.json()['secret']}"}


def _wait(client: TestClient, run_id: str, done: Any, what: str, timeout_s: float = 120.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        body: dict[str, Any] = client.get(f"/api/runs/{run_id}", headers=VIEW).json()
        if done(body):
            return body
        time.sleep(0.1)
    raise AssertionError(f"run {run_id}: no {what} within {timeout_s} s")


def _requests(audit: list[dict[str, Any]]) -> list[tuple[str, str]]:
    return [(a["action"], a["actor"]) for a in audit if a["action"] != "state"]


def _states(audit: list[dict[str, Any]]) -> list[tuple[str, str]]:
    return [(a["state"], a["actor"]) for a in audit if a["action"] == "state"]


def test_pause_continue_and_abort_are_stored_with_their_operators(
    client: TestClient, grace: dict[str, str]
) -> None:
    before = dt.datetime.now(dt.UTC)
    r = client.post("/api/runs", json={"unit_serial": "SN-AUDIT", "procedure": "static-12"}, headers=ADA)
    assert r.status_code == 202, r.text
    run_id = r.json()["id"]
    _wait(client, run_id, lambda b: (b.get("last_complete_window") or -1) >= 1, "two windows")
    assert client.post(f"/api/runs/{run_id}/pause", headers=grace).status_code == 200
    wait_state(client, run_id, "paused")
    assert client.post(f"/api/runs/{run_id}/resume", headers=ADA).json()["action"] == "continue"
    _wait(
        client, run_id, lambda b: b["state"] == "running" and (b.get("last_complete_window") or 0) >= 3, "4"
    )
    assert client.post(f"/api/runs/{run_id}/abort", headers=grace).status_code == 200
    assert wait_final(client, run_id)["state"] == "aborted"
    after = dt.datetime.now(dt.UTC)

    audit = client.get(f"/api/runs/{run_id}/audit", headers=VIEW).json()
    assert _requests(audit) == [
        ("start", "Ada Lovelace"),
        ("pause", "Grace Hopper"),
        ("continue", "Ada Lovelace"),
        ("abort", "Grace Hopper"),
    ]
    states = _states(audit)
    assert states[0] == ("running", "agent") and states[-1] == ("aborted", "agent")
    assert ("paused", "agent") in states
    paused_at = states.index(("paused", "agent"))
    assert states[paused_at + 1] == ("running", "agent")  # the continue, applied by the agent
    times = [dt.datetime.fromisoformat(a["at"]) for a in audit]
    assert all(t.utcoffset() == dt.timedelta(0) for t in times)
    assert all(before <= t <= after for t in times)
    assert times == sorted(times)
    paused = next(a for a in audit if a["state"] == "paused")
    assert paused["detail"] == "operator pause" and paused["window_index"] >= 2

    body = client.get(f"/api/runs/{run_id}", headers=VIEW).json()
    assert body["started_by"] == "Ada Lovelace" and body["audit"] == audit
    listed = client.get("/api/runs", headers=VIEW).json()
    assert all(r["audit"] is None for r in listed)


def test_the_certificate_of_a_paused_run_lists_the_pause_and_who_started_it(
    client: TestClient, grace: dict[str, str]
) -> None:
    r = client.post("/api/runs", json={"unit_serial": "SN-CERT", "procedure": "static-12"}, headers=ADA)
    run_id = r.json()["id"]
    _wait(client, run_id, lambda b: (b.get("last_complete_window") or -1) >= 1, "two windows")
    assert client.post(f"/api/runs/{run_id}/pause", headers=grace).status_code == 200
    wait_state(client, run_id, "paused")
    time.sleep(1.5)
    assert client.post(f"/api/runs/{run_id}/resume", headers=ADA).status_code == 202
    body = wait_final(client, run_id)
    assert body["state"] == "completed", body["error"]

    audit = client.get(f"/api/runs/{run_id}/audit", headers=VIEW).json()
    paused = next(a for a in audit if a["state"] == "paused")
    went_on = next(a for a in audit[audit.index(paused) + 1 :] if a["action"] == "state")
    assert went_on["state"] == "running" and went_on["actor"] == "agent"
    held_s = (
        dt.datetime.fromisoformat(went_on["at"]) - dt.datetime.fromisoformat(paused["at"])
    ).total_seconds()
    assert held_s >= 1.5
    asked = next(a for a in audit if a["action"] == "pause")
    content = client.get(f"/api/runs/{run_id}/certificate", headers=VIEW).json()["content"]
    deviations = content["method"]["deviations"]
    (pause_line,) = [d for d in deviations if d.startswith("paused")]
    assert f"for {held_s:.0f} s" in pause_line and f"at window {paused['window_index']}" in pause_line
    at = dt.datetime.fromisoformat(asked["at"])
    assert f"asked by Grace Hopper at {at:%Y-%m-%d %H:%M:%S} UTC" in pause_line
    assert "none" not in " ".join(deviations)
    assert content["run_record"]["started_by"].startswith("Ada Lovelace at ")
    assert len(content["run_record"]["actions"]) == len(audit)
    pdf = client.get(f"/api/runs/{run_id}/certificate.pdf", headers=ADA)
    assert pdf.status_code == 200 and pdf.content.startswith(b"%PDF")


def test_a_queued_abort_and_an_unnamed_token(client: TestClient, grace: dict[str, str]) -> None:
    """A run aborted while queued: the request by its operator and the state by the service; a
    configured token without a name is stored as such, never as nobody."""
    first = client.post("/api/runs", json={"unit_serial": "SN-HOLD", "procedure": "static-12"}, headers=grace)
    first_id = first.json()["id"]
    wait_state(client, first_id, "running")
    from tests.support.service_helpers import OP

    queued = client.post("/api/runs", json={"unit_serial": "SN-Q", "procedure": "static-12"}, headers=OP)
    queued_id = queued.json()["id"]
    assert client.post(f"/api/runs/{queued_id}/abort", headers=ADA).json()["state"] == "aborted"
    audit = client.get(f"/api/runs/{queued_id}/audit", headers=VIEW).json()
    assert _requests(audit) == [
        ("start", "operator token of CALBENCH_TOKENS (no operator name)"),
        ("abort", "Ada Lovelace"),
    ]
    assert _states(audit) == [("aborted", "system")]
    assert client.post(f"/api/runs/{first_id}/abort", headers=grace).status_code == 200
    wait_final(client, first_id)
    assert client.get("/api/runs/no-such-run/audit", headers=VIEW).status_code == 404


def test_tokens_for_operators_must_name_one(client: TestClient) -> None:
    r = client.post("/api/tokens", json={"role": "operator", "label": "bench PC"}, headers=ADMIN)
    assert r.status_code == 422 and "operator" in r.text
    r = client.post("/api/tokens", json={"role": "viewer", "label": "wall"}, headers=ADMIN)
    assert r.status_code == 201 and r.json()["operator"] == ""
