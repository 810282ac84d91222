"""The dashboard's documents: ETag and 304 only for an unchanged document, a changed one at once,
answers kept per database revision (health also for at most its max age), and the token
checked on every request."""

from __future__ import annotations

import asyncio
import hashlib
import sqlite3
from collections.abc import Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

import api.doc_cache
import api.routes.units
from api.db_revision import DatabaseRevision
from api.doc_cache import Captured, Document, DocumentStore, etag_of, matches
from api.main import create_app
from db.models import Bench
from station.runs.queue import RunQueue
from tests.support.service_helpers import OP, VIEW, service_settings

pytestmark = pytest.mark.timeout(60)


@pytest.fixture()
def client(tmp_path: Path) -> Iterator[TestClient]:
    settings = service_settings(tmp_path, agent="external")  # no agent writing to the database
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        yield c


def _db(client: TestClient) -> str:
    return str(client.app.state.services.engine.url.database)  # type: ignore[attr-defined]


def _register(client: TestClient, serial: str, **fields: object) -> None:
    r = client.put(f"/api/units/{serial}", json=fields, headers=OP)
    assert r.status_code == 200, r.text


def test_an_unchanged_document_is_304_and_a_changed_one_comes_with_a_new_tag(client: TestClient) -> None:
    _register(client, "SN-C-1", description="first")
    r = client.get("/api/units", headers=VIEW)
    assert r.status_code == 200
    assert [u["description"] for u in r.json()] == ["first"]
    tag = r.headers["etag"]
    assert tag == '"' + hashlib.blake2b(r.content, digest_size=16).hexdigest() + '"'
    assert r.headers["cache-control"] == "private, no-cache"

    again = client.get("/api/units", headers={**VIEW, "If-None-Match": tag})
    assert again.status_code == 304
    assert again.content == b""
    assert again.headers["etag"] == tag
    assert again.headers["x-frame-options"] == "DENY"  # the guard heads kept answers too

    _register(client, "SN-C-1", description="second")
    changed = client.get("/api/units", headers={**VIEW, "If-None-Match": tag})
    assert changed.status_code == 200
    assert [u["description"] for u in changed.json()] == ["second"]
    assert changed.headers["etag"] != tag
    assert client.get("/api/units", headers={**VIEW, "If-None-Match": '"other"'}).status_code == 200


def test_a_commit_that_leaves_the_document_unchanged_keeps_its_tag(client: TestClient) -> None:
    _register(client, "SN-C-2")
    tag = client.get("/api/units", headers=VIEW).headers["etag"]
    services = client.app.state.services  # type: ignore[attr-defined]
    with services.sessions.begin() as s:  # another table: the units list is the same
        s.add(Bench(name="bench-other"))
    r = client.get("/api/units", headers={**VIEW, "If-None-Match": tag})
    assert r.status_code == 304


def test_a_commit_by_another_process_is_seen_on_the_next_read(client: TestClient) -> None:
    _register(client, "SN-C-3", description="before")
    first = client.get("/api/units/SN-C-3/history", headers=VIEW)
    assert first.json()["unit"]["description"] == "before"
    other = sqlite3.connect(_db(client), isolation_level=None)  # as the bench's agent writes
    try:
        other.execute("UPDATE unit SET description = 'after' WHERE serial = 'SN-C-3'")
    finally:
        other.close()
    r = client.get("/api/units/SN-C-3/history", headers={**VIEW, "If-None-Match": first.headers["etag"]})
    assert r.status_code == 200
    assert r.json()["unit"]["description"] == "after"


def test_a_kept_document_is_answered_without_the_route(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    _register(client, "SN-C-4")
    calls = []
    real = api.routes.units.list_units

    def counted(
        session: sa.orm.Session, *, search: str | None = None, limit: int | None = None, offset: int = 0
    ) -> object:
        calls.append(1)
        return real(session, search=search, limit=limit, offset=offset)

    monkeypatch.setattr(api.routes.units, "list_units", counted)
    bodies = [client.get("/api/units", headers=VIEW).content for _ in range(5)]
    assert len(calls) == 1
    assert len(set(bodies)) == 1
    _register(client, "SN-C-5")
    assert [u["serial"] for u in client.get("/api/units", headers=VIEW).json()] == ["SN-C-4", "SN-C-5"]
    assert len(calls) == 2  # the commit of the PUT: computed again, once


def test_the_token_is_checked_before_a_kept_document_is_sent(client: TestClient) -> None:
    _register(client, "SN-C-6")
    tag = client.get("/api/units", headers=VIEW).headers["etag"]
    assert client.get("/api/units").status_code == 401
    assert client.get("/api/units", headers={"If-None-Match": tag}).status_code == 401
    r = client.get("/api/units", headers={"Authorization": "Bearer not-a-token", "If-None-Match": tag})
    assert r.status_code == 401
    assert "etag" not in r.headers


def test_errors_are_not_kept_nor_tagged(client: TestClient) -> None:
    for _ in range(2):
        r = client.get("/api/runs/no-such-run", headers=VIEW)
        assert r.status_code == 404
        assert "etag" not in r.headers
    assert client.app.state.services.documents is not None  # type: ignore[attr-defined]
    assert len(client.app.state.services.documents) == 0  # type: ignore[attr-defined]


def test_other_reads_pass_untouched(client: TestClient) -> None:
    r = client.get("/api/whoami", headers=VIEW)
    assert r.status_code == 200
    assert "etag" not in r.headers


def test_health_is_kept_until_a_commit_or_for_its_max_age(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = []
    real = RunQueue.current

    def counted(self: RunQueue) -> object:
        calls.append(1)
        return real.fget(self)  # type: ignore[attr-defined]

    monkeypatch.setattr(RunQueue, "current", property(counted))
    monkeypatch.setattr(api.doc_cache, "HEALTH_MAX_AGE_S", 60.0)
    answers = [client.get("/api/health") for _ in range(3)]  # liveness needs no token
    assert [a.status_code for a in answers] == [200] * 3
    assert answers[0].json()["busy_run"] is None
    assert len(calls) == 1
    _register(client, "SN-C-7")  # a commit
    client.get("/api/health")
    assert len(calls) == 2
    monkeypatch.setattr(api.doc_cache, "HEALTH_MAX_AGE_S", 0.0)  # too old at once: the clock moved
    client.get("/api/health")
    client.get("/api/health")
    assert len(calls) == 4


def test_if_none_match_comparison() -> None:
    tag = etag_of(b"{}")
    assert matches(tag, tag)
    assert matches(f'"x", W/{tag}', tag)
    assert matches("*", tag)
    assert not matches(None, tag)
    assert not matches('"x"', tag)
    assert etag_of(b"{}") == tag
    assert etag_of(b"[]") != tag


def test_the_revision_moves_with_every_commit_of_another_connection(tmp_path: Path) -> None:
    path = tmp_path / "r.db"
    writer = sqlite3.connect(path, isolation_level=None)
    writer.execute("PRAGMA journal_mode = WAL")
    writer.execute("CREATE TABLE t (x)")
    revision = DatabaseRevision(sa.make_url(f"sqlite:///{path}"))

    def now() -> object:
        return asyncio.run(revision.current())

    try:
        seen = [now()]
        seen.append(now())
        writer.execute("INSERT INTO t VALUES (1)")
        seen.append(now())
        writer.execute("BEGIN IMMEDIATE")  # a write not yet committed changes nothing
        writer.execute("INSERT INTO t VALUES (2)")
        seen.append(now())
        writer.execute("COMMIT")
        seen.append(now())
    finally:
        writer.close()
        revision.close()
    assert None not in seen
    assert seen[0] == seen[1] != seen[2] == seen[3] != seen[4]
    assert now() is None  # closed
    assert asyncio.run(DatabaseRevision(sa.make_url("mysql://u@127.0.0.1/db")).current()) is None


def _doc(body: bytes, revision: int = 1) -> Document:
    return Document(revision, etag_of(body), b"application/json", body)


def test_the_store_keeps_the_newest_answers_within_its_bounds(tmp_path: Path) -> None:
    revision = DatabaseRevision(sa.make_url(f"sqlite:///{tmp_path / 'none.db'}"))
    by_count = DocumentStore(revision, max_entries=3, max_bytes=10_000)
    for i in range(4):
        by_count.put(f"/k{i}", _doc(b"x" * 10, revision=7))
    assert len(by_count) == 3
    assert by_count.get("/k0", 7) is None  # the least recently used went first
    assert by_count.get("/k1", 7) is not None
    assert by_count.get("/k1", 8) is None  # another revision: not exact any more

    by_bytes = DocumentStore(revision, max_entries=100, max_bytes=100)
    by_bytes.put("/big", _doc(b"y" * 26))  # more than a quarter of the bytes: not kept
    assert len(by_bytes) == 0
    for i in range(5):
        by_bytes.put(f"/k{i}", _doc(b"x" * 20))
    assert len(by_bytes) == 5  # 100 bytes: within the bound
    by_bytes.put("/k0", _doc(b"x" * 20))  # replaced, not added
    by_bytes.put("/k5", _doc(b"x" * 20))
    assert len(by_bytes) == 5
    assert by_bytes.get("/k1", 1) is None  # the least recently used went first
    assert by_bytes.get("/k0", 1) is not None


def test_requests_waiting_on_the_same_document_compute_it_once(tmp_path: Path) -> None:
    store = DocumentStore(DatabaseRevision(sa.make_url(f"sqlite:///{tmp_path / 'none.db'}")))
    computed = []

    async def compute() -> Captured:
        computed.append(1)
        await asyncio.sleep(0.05)
        captured = Captured()
        json_type = [(b"content-type", b"application/json")]
        await captured.send({"type": "http.response.start", "status": 200, "headers": json_type})
        await captured.send({"type": "http.response.body", "body": b'{"a": 1}'})
        return captured

    async def main() -> list[tuple[Document | None, Captured | None]]:
        return await asyncio.gather(*(store.once("/k", 5, compute) for _ in range(10)))

    results = asyncio.run(main())
    assert len(computed) == 1
    assert [d.body if d else None for d, _ in results] == [b'{"a": 1}'] * 10
    assert sum(c is not None for _, c in results) == 1  # only the one that computed has the answer
    assert store.get("/k", 5) is not None
