"""Every read path survives a stored row it cannot parse (issue 24, item 3).

A run whose ``params`` is not JSON or whose ``created_at`` is not a time (written by another
tool, or a damaged database) is shown as unreadable, with the parser's message, and the other
runs are served: the run list, the run's own page, the unit's history and trends, the event
stream. Text with a lone UTF-16 surrogate is refused at the input layer (422), never stored.
"""

from __future__ import annotations

import json
import sqlite3
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from tests.support.service_helpers import OP, VIEW, service_settings

pytestmark = pytest.mark.timeout(120)
ADMIN_SECRET = "admin-secret-0001"
ADMIN = {"Authorization": f"Bearer {ADMIN_SECRET}"}


@pytest.fixture()
def client(tmp_path: Path) -> Iterator[TestClient]:
    settings = service_settings(tmp_path)
    settings = settings.model_copy(update={"tokens": [*settings.tokens, f"admin:{ADMIN_SECRET}"]})
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        yield c


def _queued_then_aborted(client: TestClient, serial: str) -> str:
    run_id: str = client.post(
        "/api/runs", json={"unit_serial": serial, "procedure": "static-12"}, headers=OP
    ).json()["id"]
    client.post(f"/api/runs/{run_id}/abort", headers=OP)
    services = client.app.state.services  # type: ignore[attr-defined]
    deadline = time.monotonic() + 60
    while services.runner.current is not None and time.monotonic() < deadline:
        time.sleep(0.1)
    return run_id


def _damage(db: Path, run_id: str, column: str, text: str) -> None:
    con = sqlite3.connect(db)
    with con:
        con.execute(f"UPDATE run SET {column} = ? WHERE id = ?", (text, run_id))
    con.close()


@pytest.mark.parametrize(
    ("column", "text", "message"),
    [
        ("params", '{"bench": "bench-api", ', "params"),
        ("params", "not json at all", "params"),
        ("created_at", "yesterday at noon", "created_at"),
        ("created_at", "2026-13-45 99:00:00", "created_at"),
    ],
)
def test_an_unreadable_run_is_shown_as_such_and_the_rest_served(
    client: TestClient, tmp_path: Path, column: str, text: str, message: str
) -> None:
    good = _queued_then_aborted(client, "SN-ROW")
    bad = _queued_then_aborted(client, "SN-ROW")
    _damage(tmp_path / "calbench.db", bad, column, text)

    r = client.get("/api/runs", headers=VIEW)
    assert r.status_code == 200, r.text
    by_id = {x["id"]: x for x in r.json()}
    assert by_id[good]["unreadable"] is None and by_id[good]["state"] == "aborted"
    assert by_id[bad]["unreadable"].startswith(message), by_id[bad]
    assert by_id[bad]["state"] == "aborted"  # what can be read still is

    one = client.get(f"/api/runs/{bad}", headers=VIEW)
    assert one.status_code == 200, one.text
    assert one.json()["unreadable"] == by_id[bad]["unreadable"]

    hist = client.get("/api/units/SN-ROW/history", headers=VIEW)
    assert hist.status_code == 200, hist.text
    assert {x["id"] for x in hist.json()["runs"]} == {good, bad}
    assert client.get("/api/units/SN-ROW/plots/history", headers=VIEW).status_code == 200
    assert client.get(f"/api/runs/{bad}/diagnosis", headers=VIEW).status_code in (200, 404)

    with client.stream("GET", f"/api/runs/{bad}/events", headers=VIEW) as s:
        assert s.status_code == 200
        first = next(line for line in s.iter_lines() if line.startswith("event:"))
    assert first in ("event: state", "event: finished")


@pytest.mark.parametrize(
    ("method", "path", "body"),
    [
        ("post", "/api/links", '{"path": "/api/runs/x\\ud800/events"}'),
        ("post", "/api/runs", '{"unit_serial": "SN-\\ud800", "procedure": "static-12"}'),
        ("post", "/api/tokens", '{"role": "viewer", "label": "\\udfff"}'),
        ("put", "/api/units/SN-SUR", '{"customer_name": "A\\ud83d"}'),
    ],
)
def test_a_lone_surrogate_in_a_json_body_is_422(
    client: TestClient, method: str, path: str, body: str
) -> None:
    r = client.request(method, path, content=body, headers={**ADMIN, "content-type": "application/json"})
    assert r.status_code == 422, r.text
    assert "surrogate" in json.dumps(r.json())


def test_a_paired_surrogate_escape_is_one_character(client: TestClient) -> None:
    body = '{"customer_name": "Acme \\ud83d\\ude00"}'
    r = client.put("/api/units/SN-EMO", content=body, headers={**OP, "content-type": "application/json"})
    assert r.status_code == 200 and r.json()["customer_name"] == "Acme \U0001f600"


def test_an_upload_whose_serial_holds_a_lone_surrogate_is_refused_as_it_is_read(client: TestClient) -> None:
    csv = "t,ax,ay,az\n" + "".join(f"{i / 100},0,0,9.8\n" for i in range(10))
    sidecar = (
        '{"format": "calbench-recording/1", "unit": {"serial": "SN-\\ud800"}, "channel_unit": "m/s2", '
        '"sample_rate_hz": 100.0, "g_local_m_s2": 9.81}'
    )
    files = {"recording": ("run.csv", csv, "text/csv"), "sidecar": ("run.json", sidecar, "application/json")}
    r = client.post("/api/recordings", files=files, headers=OP)
    assert r.status_code == 422, r.text
    assert "surrogate" in r.json()["detail"] and "unit.serial" in r.json()["detail"]
