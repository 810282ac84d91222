"""Reads do not wait for the write lock (SQLite), and admin-managed database tokens.

A write transaction is held open (``BEGIN IMMEDIATE`` on SQLite) while GET requests are
served: if a read took the write lock it would wait for the busy timeout (30 s) and fail,
which the pytest timeout bounds. The reads see the last committed state, not the open write.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from db.engine import ReadOnlySessionError
from db.models import Unit
from db.repo.units import get_or_create_unit
from tests.support.service_helpers import OP, VIEW, service_settings

pytestmark = pytest.mark.timeout(60)
ADMIN_SECRET = "admin-secret-0001"
ADMIN = {"Authorization": f"Bearer {ADMIN_SECRET}"}


@pytest.fixture()
def client(tmp_path: Path) -> Iterator[TestClient]:
    settings = service_settings(tmp_path)
    settings = settings.model_copy(update={"tokens": [*settings.tokens, f"admin:{ADMIN_SECRET}"]})
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        yield c


def _serials(client: TestClient, headers: dict[str, str]) -> list[str]:
    r = client.get("/api/units", headers=headers)
    assert r.status_code == 200, r.text
    return [u["serial"] for u in r.json()]


def test_reads_are_served_while_a_write_transaction_is_open(client: TestClient) -> None:
    services = client.app.state.services  # type: ignore[attr-defined]
    made = client.post("/api/tokens", json={"role": "viewer", "label": "wall"}, headers=ADMIN).json()
    db_viewer = {"Authorization": f"Bearer {made['secret']}"}
    with services.sessions.begin() as s:
        get_or_create_unit(s, "SN-COMMITTED")
    with services.sessions.begin() as s:  # holds the write lock until the block ends
        get_or_create_unit(s, "SN-UNCOMMITTED")
        assert _serials(client, VIEW) == ["SN-COMMITTED"]
        assert _serials(client, db_viewer) == ["SN-COMMITTED"]  # a database token, looked up
        assert client.get("/api/runs", headers=VIEW).status_code == 200
        assert client.get("/api/health").json()["database_ok"] is True
        assert client.get("/api/units/SN-UNCOMMITTED/history", headers=VIEW).status_code == 404
    assert _serials(client, VIEW) == ["SN-COMMITTED", "SN-UNCOMMITTED"]


def test_a_read_session_refuses_to_write(client: TestClient) -> None:
    services = client.app.state.services  # type: ignore[attr-defined]
    with pytest.raises(ReadOnlySessionError, match="Unit"), services.read_sessions.begin() as s:
        s.add(Unit(serial="SN-NEVER"))
    assert _serials(client, VIEW) == []


def test_admin_creates_lists_and_revokes_tokens(client: TestClient) -> None:
    r = client.post(
        "/api/tokens",
        json={"role": "operator", "label": "bench PC", "operator": "Ada Lovelace"},
        headers=ADMIN,
    )
    assert r.status_code == 201, r.text
    made = r.json()
    assert made["role"] == "operator" and made["label"] == "bench PC" and len(made["secret"]) >= 32
    assert made["operator"] == "Ada Lovelace"
    op = {"Authorization": f"Bearer {made['secret']}"}
    assert client.get("/api/whoami", headers=op).json() == {"role": "operator"}

    listed = client.get("/api/tokens", headers=ADMIN).json()
    assert [(t["id"], t["role"], t["revoked_at"]) for t in listed] == [(made["id"], "operator", None)]
    assert all("secret" not in t and made["secret"] not in str(t) for t in listed)

    r = client.delete(f"/api/tokens/{made['id']}", headers=ADMIN)
    assert r.status_code == 200 and r.json()["revoked_at"] is not None
    assert client.get("/api/whoami", headers=op).status_code == 401
    assert client.delete(f"/api/tokens/{made['id']}", headers=ADMIN).status_code == 409
    assert client.delete("/api/tokens/999999", headers=ADMIN).status_code == 404


def test_last_use_of_a_database_token_is_recorded(client: TestClient) -> None:
    made = client.post("/api/tokens", json={"role": "viewer"}, headers=ADMIN).json()
    assert client.get("/api/whoami", headers={"Authorization": f"Bearer {made['secret']}"}).status_code == 200
    services = client.app.state.services  # type: ignore[attr-defined]
    services.auth.close()  # waits for the background write
    (row,) = client.get("/api/tokens", headers=ADMIN).json()
    assert row["last_used_at"] is not None


@pytest.mark.parametrize(("headers", "status"), [({}, 401), (VIEW, 403), (OP, 403)])
def test_token_management_is_admin_only(client: TestClient, headers: dict[str, str], status: int) -> None:
    assert client.get("/api/tokens", headers=headers).status_code == status
    made = client.post("/api/tokens", json={"role": "admin", "operator": "Grace Hopper"}, headers=headers)
    assert made.status_code == status
    assert client.delete("/api/tokens/1", headers=headers).status_code == status


def test_bad_token_request_names_the_field(client: TestClient) -> None:
    r = client.post("/api/tokens", json={"role": "root"}, headers=ADMIN)
    assert r.status_code == 422 and "role" in r.text
    r = client.post("/api/tokens", json={"role": "viewer", "lable": "x"}, headers=ADMIN)
    assert r.status_code == 422 and "lable" in r.text


def test_unit_registration_updates_given_fields_and_refuses_bad_ones(client: TestClient) -> None:
    r = client.put("/api/units/SN-REG", json={"customer_name": "Acme", "nominal_scale": 0.0177}, headers=OP)
    assert r.status_code == 200, r.text
    change = {"customer_address": "1 Road", "customer_name": None}
    body = client.put("/api/units/SN-REG", json=change, headers=OP).json()
    assert body["customer_name"] is None and body["customer_address"] == "1 Road"
    assert body["nominal_scale"] == 0.0177
    for bad, field in (
        ({"nominal_scale": 0}, "nominal_scale"),
        ({"received_on": "yesterday"}, "received_on"),
        ({"colour": "red"}, "colour"),
        ({"channel_unit": "mV"}, "channel_unit"),
    ):
        r = client.put("/api/units/SN-REG", json=bad, headers=OP)
        assert r.status_code == 422 and field in r.text, (bad, r.text)
    assert client.put("/api/units/bad%20serial", json={}, headers=OP).status_code == 422
    assert client.put("/api/units/SN-REG", json={}, headers=VIEW).status_code == 403
