"""The document cache on PostgreSQL: the revision (``pg_current_snapshot()``) moves with every
commit of another connection or process and not without one, a kept document is answered
without its route, a commit by another process is seen on the next read, and while the
revision's connection is gone (a closed port, a terminated backend) every request is still
answered, computed afresh, and the connection comes back after its pause.

The server is shared: commits to other databases of it change the snapshot too (it is
cluster-wide, by design never stale), so the checks that a value or a kept answer *stays* retry
a few times for a quiet moment instead of expecting one on the first try.
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import psycopg
import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

import api.pg_revision
import api.routes.units
from api.db_revision import DatabaseRevision
from api.main import create_app
from api.pg_revision import APPLICATION_NAME, SnapshotRevision
from db.notify import listen_url
from tests.support.service_helpers import OP, VIEW, service_settings

pytestmark = [pytest.mark.postgres, pytest.mark.timeout(120)]

QUIET_TRIES = 30
"""Attempts at a moment without commits elsewhere on the shared server."""


@pytest.fixture()
def client(tmp_path: Path, pg_url: str) -> Iterator[TestClient]:
    settings = service_settings(tmp_path, database_url=pg_url, agent="external")
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        _wait_connected(c)
        yield c


def _reader(client: TestClient) -> SnapshotRevision:
    reader = client.app.state.services.documents.revision.postgresql  # type: ignore[attr-defined]
    assert isinstance(reader, SnapshotRevision)
    return reader


def _wait_connected(client: TestClient, timeout_s: float = 10.0) -> None:
    """Requests until the revision's connection (opened in the background) is up."""
    deadline = time.monotonic() + timeout_s
    while not _reader(client).connected:
        assert time.monotonic() < deadline, "the revision's connection did not come up"
        assert client.get("/api/health").status_code == 200
        time.sleep(0.05)


def _register(client: TestClient, serial: str, **fields: object) -> None:
    r = client.put(f"/api/units/{serial}", json=fields, headers=OP)
    assert r.status_code == 200, r.text


def _description(units: httpx.Response, serial: str) -> object:
    """The description of ``serial`` in a units list (the database is the test module's)."""
    return {u["serial"]: u["description"] for u in units.json()}[serial]


def _conninfo(url: str) -> str:
    conninfo = listen_url(url)
    assert conninfo is not None
    return conninfo


def test_the_snapshot_moves_with_every_commit_and_not_without_one(pg_url: str) -> None:
    conninfo = _conninfo(pg_url)
    revision = DatabaseRevision(sa.make_url(pg_url))
    writer = psycopg.connect(conninfo, autocommit=True)
    other_process = (
        "import psycopg, sys\n"
        "with psycopg.connect(sys.argv[1], autocommit=True) as c:\n"
        "    c.execute('INSERT INTO t VALUES (3)')\n"
    )

    async def scenario() -> tuple[list[object], list[bool], list[bool]]:
        now = revision.current
        deadline = time.monotonic() + 10.0
        while await now() is None:  # the connection opens in the background
            assert time.monotonic() < deadline
            await asyncio.sleep(0.02)
        writer.execute("CREATE TABLE IF NOT EXISTS t (x int)")
        seen = [await now()]
        writer.execute("INSERT INTO t VALUES (1)")  # a commit of another connection
        seen.append(await now())
        await asyncio.to_thread(subprocess.run, [sys.executable, "-c", other_process, conninfo], check=True)
        seen.append(await now())  # a commit of another process
        quiet = [(await now()) == (await now()) for _ in range(QUIET_TRIES)]
        writer.execute("BEGIN")
        writer.execute("INSERT INTO t VALUES (2)")  # a write not yet committed changes nothing
        uncommitted = [(await now()) == (await now()) for _ in range(QUIET_TRIES)]
        before = await now()
        writer.execute("COMMIT")
        seen += [before, await now()]
        return seen, quiet, uncommitted

    try:
        seen, quiet, uncommitted = asyncio.run(scenario())
    finally:
        writer.close()
        revision.close()
    assert None not in seen
    assert seen[0] != seen[1] != seen[2]
    assert seen[3] != seen[4]
    assert any(quiet), "the snapshot changed between every two reads without a commit of ours"
    assert any(uncommitted)
    assert asyncio.run(revision.current()) is None  # closed


def test_requests_share_a_read_that_starts_after_they_came(pg_url: str) -> None:
    reader = SnapshotRevision(_conninfo(pg_url))
    queries: list[str] = []

    async def scenario() -> list[str | None]:
        while await reader.current() is None:
            await asyncio.sleep(0.02)
        conn = reader._conn
        assert conn is not None
        execute = conn.execute

        async def counted(query: str) -> object:
            queries.append(query)
            return await execute(query)  # type: ignore[arg-type]

        conn.execute = counted  # type: ignore[assignment,method-assign]
        first = asyncio.ensure_future(reader.current())
        while not queries:  # its read is under way
            await asyncio.sleep(0)
        later = [reader.current() for _ in range(19)]
        return [await first, *await asyncio.gather(*later)]

    try:
        values = asyncio.run(scenario())
    finally:
        reader.close()
    assert None not in values
    # the first request's read was under way when the 19 others came: they share the next one
    assert len(queries) == 2


def test_a_closed_port_gives_no_revision_and_is_retried_after_a_pause(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    attempts = []
    real = psycopg.AsyncConnection.connect

    async def counted(*args: object, **kwargs: object) -> object:
        attempts.append(time.monotonic())
        return await real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(psycopg.AsyncConnection, "connect", counted)
    monkeypatch.setattr(api.pg_revision, "RETRY_FIRST_S", 0.3)
    reader = SnapshotRevision(f"postgresql://postgres@127.0.0.1:{port}/test")

    async def scenario() -> list[str | None]:
        values = []
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            values.append(await reader.current())
            await asyncio.sleep(0.01)
        return values

    values = asyncio.run(scenario())
    reader.close()
    assert set(values) == {None}
    assert len(values) > 50
    # refused at once, then retried after 0.3 s and 0.6 s: 2 or 3 attempts in 1 s, not one a request
    assert 2 <= len(attempts) <= 3
    assert attempts[1] - attempts[0] >= 0.3


def test_a_kept_document_is_answered_without_the_route(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    _register(client, "SN-PG-1")
    calls = []
    real = api.routes.units.list_units

    def counted(
        session: sa.orm.Session, *, search: str | None = None, limit: int | None = None, offset: int = 0
    ) -> object:
        calls.append(1)
        return real(session, search=search, limit=limit, offset=offset)

    monkeypatch.setattr(api.routes.units, "list_units", counted)
    kept = 0
    for _ in range(QUIET_TRIES):
        n = len(calls)
        first = client.get("/api/units", headers=VIEW)
        again = client.get("/api/units", headers={**VIEW, "If-None-Match": first.headers["etag"]})
        assert again.status_code == 304
        kept += len(calls) == n + 1  # the second came from the kept answer
        if kept:
            break
    assert kept, "no two reads without a commit on the server in between"
    _register(client, "SN-PG-2")
    n = len(calls)
    r = client.get("/api/units", headers=VIEW)
    assert {"SN-PG-1", "SN-PG-2"} <= {u["serial"] for u in r.json()}  # the database is the module's
    assert len(calls) == n + 1  # the commit of the PUT: computed again


def test_a_commit_by_another_process_is_seen_on_the_next_read(client: TestClient, pg_url: str) -> None:
    _register(client, "SN-PG-3", description="before")
    first = client.get("/api/units/SN-PG-3/history", headers=VIEW)
    assert first.json()["unit"]["description"] == "before"
    script = (
        "import psycopg, sys\n"
        "with psycopg.connect(sys.argv[1], autocommit=True) as c:\n"
        "    c.execute(\"UPDATE unit SET description = 'after' WHERE serial = 'SN-PG-3'\")\n"
    )
    subprocess.run([sys.executable, "-c", script, _conninfo(pg_url)], check=True)
    r = client.get("/api/units/SN-PG-3/history", headers={**VIEW, "If-None-Match": first.headers["etag"]})
    assert r.status_code == 200
    assert r.json()["unit"]["description"] == "after"


def test_requests_are_answered_while_the_revision_connection_is_gone(
    client: TestClient, pg_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(api.pg_revision, "RETRY_FIRST_S", 0.2)
    reader = _reader(client)
    reader._pause_s = 0.2
    _register(client, "SN-PG-4", description="one")
    assert client.get("/api/units", headers=VIEW).status_code == 200
    database = sa.make_url(pg_url).database
    with psycopg.connect(_conninfo(pg_url), autocommit=True) as admin:  # only this test's database
        ended = admin.execute(
            "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity"
            " WHERE application_name = %s AND datname = %s",
            (APPLICATION_NAME, database),
        ).fetchone()
    assert ended == (1,)
    _register(client, "SN-PG-4", description="two")
    r = client.get("/api/units", headers=VIEW)  # the read fails: computed afresh
    assert r.status_code == 200
    assert _description(r, "SN-PG-4") == "two"
    assert "etag" in r.headers
    assert not reader.connected
    _wait_connected(client)  # back after its pause
    _register(client, "SN-PG-4", description="three")
    assert _description(client.get("/api/units", headers=VIEW), "SN-PG-4") == "three"
