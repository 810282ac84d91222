"""Token guesses are limited per client (429 with Retry-After) and a stalled body is cut off (408)
(issue 24, item 8)."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

import api.error_handlers
import api.guard
from api.failed_auth import MAX_AUTH_FAILURES, FailedAuthLimiter
from api.main import create_app
from tests.support.service_helpers import OP, VIEW, service_settings

pytestmark = pytest.mark.timeout(120)


@pytest.fixture()
def client(tmp_path: Path) -> Iterator[TestClient]:
    with TestClient(create_app(service_settings(tmp_path), start_scheduler=False)) as c:
        yield c


def test_token_guesses_past_the_limit_are_answered_429_with_retry_after(client: TestClient) -> None:
    for i in range(MAX_AUTH_FAILURES):
        assert client.get("/api/runs", headers={"Authorization": f"Bearer guess-{i:04d}"}).status_code == 401
    r = client.get("/api/runs", headers={"Authorization": "Bearer guess-next"})
    assert r.status_code == 429 and 1 <= int(r.headers["retry-after"]) <= 60
    assert "too many failed authentications" in r.json()["detail"]
    assert client.get("/api/runs", headers=VIEW).status_code == 429  # even the right one: by client
    assert client.get("/api/health").status_code == 200  # no credential: not limited


def test_missing_tokens_are_not_counted_as_guesses(client: TestClient) -> None:
    for _ in range(MAX_AUTH_FAILURES + 5):
        assert client.get("/api/runs").status_code == 401
    assert client.get("/api/runs", headers=VIEW).status_code == 200


def test_the_limiter_forgets_failures_older_than_its_window() -> None:
    now = [0.0]
    lim = FailedAuthLimiter(limit=3, window_s=60.0, clock=lambda: now[0])
    for t in (0.0, 10.0, 20.0):
        now[0] = t
        assert lim.retry_after_s("a") is None
        lim.failed("a")
    assert lim.retry_after_s("a") == pytest.approx(40.0)
    assert lim.retry_after_s("b") is None
    now[0] = 60.5
    assert lim.retry_after_s("a") is None


def test_a_stalled_body_is_answered_408(client: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(api.guard, "BODY_READ_TIMEOUT_S", 0.3)
    statuses: list[int] = []
    calls = 0

    async def receive() -> dict[str, Any]:
        nonlocal calls
        calls += 1
        if calls == 1:
            return {"type": "http.request", "body": b'{"unit_serial": ', "more_body": True}
        await asyncio.sleep(3600)  # the client never sends the rest
        raise AssertionError

    async def send(message: dict[str, Any]) -> None:
        if message["type"] == "http.response.start":
            statuses.append(message["status"])

    for content_type in (b"application/json", b"multipart/form-data; boundary=x"):
        scope = {
            "type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1", "method": "POST",
            "scheme": "http", "path": "/api/runs", "raw_path": b"/api/runs", "query_string": b"",
            "root_path": "", "client": ("127.0.0.1", 1), "server": ("testserver", 80),
            "headers": [(b"authorization", OP["Authorization"].encode()), (b"content-type", content_type)],
        }  # fmt: skip
        calls = 0
        assert client.portal is not None
        client.portal.call(client.app, scope, receive, send)
    assert statuses == [408, 408]


def test_a_write_while_the_disk_is_full_is_507_and_logged_once(
    client: TestClient, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    import sqlite3

    from sqlalchemy.exc import OperationalError

    def full(*_a: object, **_k: object) -> None:
        raise OperationalError("INSERT INTO unit", {}, sqlite3.OperationalError("database or disk is full"))

    monkeypatch.setattr("api.routes.units.get_or_create_unit", full)
    monkeypatch.setattr(api.error_handlers, "_disk_full_logged", [float("-inf")])
    with caplog.at_level("ERROR", logger="api.error_handlers"):
        for _ in range(5):
            r = client.put("/api/units/SN-FULL", json={"customer_name": "Acme"}, headers=OP)
            assert r.status_code == 507 and "disk is full" in r.json()["detail"]
    assert sum("disk full" in rec.getMessage() for rec in caplog.records) == 1


def test_other_database_errors_are_not_called_a_full_disk() -> None:
    import errno
    import sqlite3

    from sqlalchemy.exc import OperationalError

    from station.disk_full import is_disk_full

    assert is_disk_full(OSError(errno.ENOSPC, "No space left on device"))
    assert not is_disk_full(OperationalError("SELECT", {}, sqlite3.OperationalError("database is locked")))
    assert not is_disk_full(OSError(errno.EACCES, "Permission denied"))


def test_a_response_that_outlives_the_body_timeout_is_not_cut(monkeypatch: pytest.MonkeyPatch) -> None:
    """After the whole body, the next message is the disconnect: a stream (server-sent events)
    waits for it as long as it runs, so no stall applies there."""
    monkeypatch.setattr(api.guard, "BODY_READ_TIMEOUT_S", 0.2)
    got: list[str] = []

    async def app(scope: Any, receive: Any, send: Any) -> None:
        got.append((await receive())["type"])
        got.append((await receive())["type"])  # waits past the timeout for the disconnect
        await send({"type": "http.response.start", "status": 200, "headers": []})
        await send({"type": "http.response.body", "body": b"ok"})

    messages = [{"type": "http.request", "body": b"", "more_body": False}, {"type": "http.disconnect"}]

    async def receive() -> dict[str, Any]:
        if len(messages) == 1:
            await asyncio.sleep(0.6)
        return messages.pop(0)

    statuses: list[int] = []

    async def send(message: dict[str, Any]) -> None:
        if message["type"] == "http.response.start":
            statuses.append(message["status"])

    scope = {
        "type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1", "method": "GET",
        "scheme": "http", "path": "/api/runs/x/events", "raw_path": b"/api/runs/x/events",
        "query_string": b"", "root_path": "", "client": ("127.0.0.1", 1), "server": ("testserver", 80),
        "headers": [],
    }  # fmt: skip
    asyncio.run(api.guard.RequestGuard(app)(scope, receive, send))
    assert got == ["http.request", "http.disconnect"] and statuses == [200]
