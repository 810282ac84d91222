"""The REST API through the real app: roles, a queue on a busy bench, 422 with a clear message,
the live event stream, abort, and a run's certificate (JSON hash, PDF)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from db.repo.certificates import canonical_sha256
from tests.support.service_helpers import (
    OP,
    VIEW,
    service_settings,
    signed_link,
    wait_final,
    wait_state,
)
from tests.support.sse import sse_events

pytestmark = [pytest.mark.slow, pytest.mark.timeout(400)]  # whole simulated runs through the service


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    app = create_app(service_settings(tmp_path_factory.mktemp("api")), start_scheduler=False)
    with TestClient(app) as c:
        yield c


@pytest.fixture(scope="module")
def completed_run(client: TestClient) -> dict[str, object]:
    r = client.post("/api/runs", json={"unit_serial": "SN-API-1", "procedure": "static-12"}, headers=OP)
    assert r.status_code == 202, r.text
    body = wait_final(client, r.json()["id"])
    assert body["state"] == "completed", body["error"]
    return body


@pytest.mark.parametrize(
    ("method", "path", "body"),
    [
        ("post", "/api/runs", {"unit_serial": "SN-X", "procedure": "static-12"}),
        ("post", "/api/runs/nope/abort", None),
        ("post", "/api/drift/run", {}),
        ("post", "/api/runs/nope/certificate", None),
    ],
)
def test_writes_need_an_operator(client: TestClient, method: str, path: str, body: object) -> None:
    call = getattr(client, method)
    kwargs = {"json": body} if body is not None else {}
    assert call(path, **kwargs).status_code == 401
    assert call(path, headers={"Authorization": "Bearer wrong-token-123"}, **kwargs).status_code == 401
    r = call(path, headers=VIEW, **kwargs)
    assert r.status_code == 403 and "operator" in r.json()["detail"]


def test_reads_need_a_viewer_token(client: TestClient) -> None:
    assert client.get("/api/runs").status_code == 401
    assert client.get("/api/units", headers={"Authorization": "Bearer wrong-token-123"}).status_code == 401
    assert client.get("/api/units", headers=VIEW).status_code == 200
    assert client.get("/api/whoami", headers=OP).json() == {"role": "operator"}
    assert client.get("/api/health").json()["status"] == "ok"  # liveness needs no token


def test_public_read_opens_reads_but_not_writes(tmp_path: Path) -> None:
    app = create_app(service_settings(tmp_path, public_read=True), start_scheduler=False)
    with TestClient(app) as c:
        assert c.get("/api/whoami").json() == {"role": "anonymous"}
        assert c.get("/api/units", headers={"Authorization": "Bearer wrong-token-123"}).status_code == 401
        assert c.post("/api/runs", json={"unit_serial": "SN-X", "procedure": "static-12"}).status_code == 401


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"unit_serial": "SN-1", "procedure": "static-99"}, "unknown procedure 'static-99'"),
        (
            {"unit_serial": "SN-1", "procedure": "static-12", "parameters": {"window_s": 5}},
            "procedure 'static-12' takes no parameter window_s",
        ),
        ({"procedure": "static-12"}, "unit_serial"),
        ({"unit_serial": "bad serial!", "procedure": "static-12"}, "unit_serial"),
        ({"unit_serial": "SN-1", "procedure": "static-12", "dwell_s": -1}, "dwell_s"),
        ({"unit_serial": "SN-1", "procedure": "static-12", "dwel_s": 2}, "dwel_s"),
    ],
)
def test_bad_bodies_are_422_naming_the_field(
    client: TestClient, body: dict[str, object], needle: str
) -> None:
    r = client.post("/api/runs", json=body, headers=OP)
    assert r.status_code == 422
    assert needle in json.dumps(r.json())


def test_non_json_body_is_422(client: TestClient) -> None:
    r = client.post("/api/runs", content=b"dwell=nan", headers={**OP, "Content-Type": "application/json"})
    assert r.status_code == 422


def test_a_start_on_a_busy_bench_queues_and_abort_ends_the_run(client: TestClient) -> None:
    first = client.post("/api/runs", json={"unit_serial": "SN-BUSY", "procedure": "static-12"}, headers=OP)
    assert first.status_code == 202
    run_id = first.json()["id"]
    wait_state(client, run_id, "running")
    second = client.post("/api/runs", json={"unit_serial": "SN-OTHER", "procedure": "static-12"}, headers=OP)
    third = client.post("/api/runs", json={"unit_serial": "SN-THIRD", "procedure": "static-12"}, headers=OP)
    assert second.status_code == 202 and third.status_code == 202, (second.text, third.text)
    second_id, third_id = second.json()["id"], third.json()["id"]
    # Queued behind the first: an abort of a queued run ends it at once, without the table.
    assert client.get(f"/api/runs/{second_id}", headers=VIEW).json()["state"] == "queued"
    r = client.post(f"/api/runs/{second_id}/abort", headers=OP)
    assert r.status_code == 200 and r.json()["state"] == "aborted", r.text
    queued_abort = client.get(f"/api/runs/{second_id}", headers=VIEW).json()
    assert queued_abort["state"] == "aborted" and "before it started" in queued_abort["error"]
    assert client.get("/api/health").json()["busy_run"] == run_id
    r = client.post(f"/api/runs/{run_id}/abort", headers=OP)
    assert r.status_code == 200 and r.json()["abort_requested"] is True
    body = wait_final(client, run_id)
    assert body["state"] == "aborted"
    assert client.post(f"/api/runs/{run_id}/abort", headers=OP).status_code == 409
    assert client.get(f"/api/runs/{run_id}/certificate", headers=VIEW).status_code == 404
    # The third run was queued behind both: the agent takes it once the bench is free.
    wait_state(client, third_id, "running")
    assert client.post(f"/api/runs/{third_id}/abort", headers=OP).status_code == 200
    assert wait_final(client, third_id)["state"] == "aborted"


def test_unknown_run_is_404(client: TestClient) -> None:
    assert client.get("/api/runs/does-not-exist", headers=VIEW).status_code == 404
    assert client.get("/api/units/NOPE/history", headers=VIEW).status_code == 404


def test_event_stream_follows_a_run_to_its_end(client: TestClient) -> None:
    r = client.post("/api/runs", json={"unit_serial": "SN-SSE", "procedure": "static-12"}, headers=OP)
    run_id = r.json()["id"]
    with client.stream("GET", signed_link(client, f"/api/runs/{run_id}/events")) as s:
        assert s.headers["content-type"].startswith("text/event-stream")
        events = list(sse_events(s.iter_lines()))
    names = [e for e, _ in events]
    assert names[-1] == "finished" and events[-1][1]["state"] == "completed"
    assert events[-1][1]["certificate_number"]
    progress = [float(d["progress"]) for e, d in events if e == "progress"]  # type: ignore[arg-type]
    assert len(progress) > 3 and all(0.0 <= p <= 1.0 for p in progress)
    assert progress == sorted(progress)  # never goes backwards
    assert names.count("window") == 12
    wait_final(client, run_id)


def test_certificate_json_hash_and_pdf(client: TestClient, completed_run: dict[str, object]) -> None:
    run_id = completed_run["id"]
    cert = client.get(f"/api/runs/{run_id}/certificate", headers=VIEW).json()
    content = cert["content"]
    assert cert["sha256"] == canonical_sha256(content)  # hash of the canonical JSON, recomputed here
    assert content["number"] == cert["number"] == completed_run["certificate_number"]
    cal = completed_run["calibration"]
    assert isinstance(cal, dict)
    bias = content["results"]["bias"]
    u = np.asarray(bias["expanded_uncertainty"])
    budget = content["results"]["uncertainty_budget"]["quantities"]
    u_c = np.array([budget[n]["u_c"] for n in ("b_x", "b_y", "b_z")])
    np.testing.assert_allclose(u, bias["k"] * u_c, rtol=0.051)  # two digits of k·u_c (Type A + Type B)
    type_a = np.array([budget[n]["contributions"][0]["contribution"] for n in ("b_x", "b_y", "b_z")])
    assert np.all(u_c >= type_a * 0.999)  # never below the Type A part (three digits)
    np.testing.assert_allclose(bias["value"], cal["bias"], atol=float(u.max()) / 10)
    assert content["results"]["scale_matrix"]["unit"] == "V/(m/s2)"
    for key in ("traceability", "conditions", "g_check", "diagnosis", "method", "item", "end"):
        assert key in content
    assert "SIMULATED" in content["traceability"]
    assert content["conditions"]["g_local_m_s2"] > 9.7
    pdf = client.get(signed_link(client, f"/api/runs/{run_id}/certificate.pdf"))
    assert pdf.status_code == 200 and pdf.content.startswith(b"%PDF")
    again = client.post(f"/api/runs/{run_id}/certificate", headers=OP)
    assert again.status_code == 409
    by_number = client.get(f"/api/certificates/{cert['number']}", headers=VIEW).json()
    assert by_number["sha256"] == cert["sha256"]


def test_unit_history_lists_the_run_and_its_certificate(
    client: TestClient, completed_run: dict[str, object]
) -> None:
    hist = client.get("/api/units/SN-API-1/history", headers=VIEW).json()
    assert [r["id"] for r in hist["runs"]] == [completed_run["id"]]
    assert hist["certificates"][0]["number"] == completed_run["certificate_number"]
    units = {u["serial"]: u for u in client.get("/api/units", headers=VIEW).json()}
    assert units["SN-API-1"]["last_certificate"] == completed_run["certificate_number"]
