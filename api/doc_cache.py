"""The dashboard's documents: ETags, ``304 Not Modified``, and each answer kept per database revision.

The dashboard reads the same few JSON documents over and over while a run records (the run,
the runs list, the units list, a unit's history). :class:`DocumentCache` (pure ASGI, inside
:class:`api.guard.RequestGuard`) answers a ``GET`` of one of them:

1. it checks the caller's token as the route would (a viewer, or none with ``public_read``);
   when that fails the request goes on to the route, which answers the 401/403;
2. it reads the database's revision (:class:`api.db_revision.DatabaseRevision`: a few µs on
   SQLite, one round trip shared by concurrent requests on PostgreSQL); a document computed at
   the same revision is still exact, since nothing was committed since, so its stored bytes are
   the answer, without a route, a session or a serialisation;
3. otherwise the route computes it once for all the requests waiting on the same path (the
   others wait for that one), and a ``200`` JSON answer is stored with the revision read
   *before* it was computed (so it is at least as new as that revision).

Every such answer carries ``ETag`` (a hash of the body: an unchanged document keeps its tag
when other data change) and ``Cache-Control: private, no-cache``; a request whose
``If-None-Match`` names the tag gets ``304`` with no body (RFC 9110 §13.1.2, §15.4.5).
Without a revision (another backend, or the revision's reader failed) every document is
computed afresh and tagged in the same way.

The documents kept are the ones whose content depends on the database alone (no clock, no
process state): ``GET /api/runs``, ``/api/runs/{id}``, ``/api/runs/{id}/diagnosis``,
``/api/units``, ``/api/units/{serial}/history`` and ``/api/units/{serial}/plots/history``,
and the plots of a run (``/api/runs/{id}/plots/...``), which also read its recording: the
routes plot only a run that has ended, whose recording no longer changes (a resumed run
records again, and its state changes are commits). ``GET /api/health`` (no token) is kept too,
but for at most :data:`HEALTH_MAX_AGE_S`: besides the database it reads the clock and whether
the process storing a finished run's results is alive, which change without a commit.
"""

from __future__ import annotations

import asyncio
import hashlib
import re
import time
from collections import OrderedDict
from collections.abc import Awaitable, Callable, MutableMapping
from dataclasses import dataclass
from typing import Any

import anyio.to_thread

from api.auth import Authenticator, AuthError, Role
from api.db_revision import DatabaseRevision, Revision

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

KEPT = re.compile(
    r"^/api/(runs|runs/[^/]+|runs/[^/]+/(diagnosis|plots/[a-z-]+)|units|units/[^/]+/(history|plots/history))$"
)
"""Paths (viewer token) whose ``200`` answers are kept per revision (see the module docstring)."""
HEALTH_PATH = "/api/health"
HEALTH_MAX_AGE_S = 1.0
"""The longest a kept health answer is used (s), even when nothing was committed."""
CACHE_CONTROL = b"private, no-cache"
MAX_ENTRIES = 256
MAX_BYTES = 32 * 1024 * 1024
"""Bounds of the kept answers (least recently used go first)."""


def etag_of(body: bytes) -> str:
    """A strong entity tag of ``body``: 128 bits of its BLAKE2b hash, quoted."""
    return '"' + hashlib.blake2b(body, digest_size=16).hexdigest() + '"'


def matches(if_none_match: str | None, etag: str) -> bool:
    """``If-None-Match`` names ``etag`` (weak comparison, RFC 9110 §13.1.2; ``*`` matches)."""
    if not if_none_match:
        return False
    tags = [t.strip() for t in if_none_match.split(",")]
    return "*" in tags or any(t.removeprefix("W/") == etag for t in tags)


@dataclass(frozen=True)
class Document:
    """A kept answer: the revision it is exact at, its tag, its media type and its bytes."""

    revision: Revision | None
    etag: str
    content_type: bytes
    body: bytes
    computed_at: float = 0.0
    """When it was computed (``time.monotonic``, s)."""


class DocumentStore:
    """The kept answers of one service, by path and query, least recently used dropped first.

    :param revision: the database's revision source.
    """

    def __init__(
        self, revision: DatabaseRevision, max_entries: int = MAX_ENTRIES, max_bytes: int = MAX_BYTES
    ) -> None:
        self.revision, self.max_entries, self.max_bytes = revision, max_entries, max_bytes
        self._docs: OrderedDict[str, Document] = OrderedDict()
        self._bytes = 0
        self._inflight: dict[tuple[str, Revision], asyncio.Future[Document | None]] = {}

    def get(self, key: str, revision: Revision, max_age_s: float | None = None) -> Document | None:
        """The answer kept for ``key`` if it is exact at ``revision`` (and, with ``max_age_s``,
        computed at most that long ago)."""
        doc = self._docs.get(key)
        if doc is None or doc.revision != revision:
            return None
        if max_age_s is not None and time.monotonic() - doc.computed_at > max_age_s:
            return None
        self._docs.move_to_end(key)
        return doc

    def put(self, key: str, doc: Document) -> None:
        """Keep ``doc`` for ``key`` (replacing the one kept), within the bounds."""
        old = self._docs.pop(key, None)
        if old is not None:
            self._bytes -= len(old.body)
        if len(doc.body) > self.max_bytes // 4:
            return
        self._docs[key] = doc
        self._bytes += len(doc.body)
        while len(self._docs) > self.max_entries or self._bytes > self.max_bytes:
            _, dropped = self._docs.popitem(last=False)
            self._bytes -= len(dropped.body)

    async def once(
        self, key: str, revision: Revision, compute: Callable[[], Awaitable[Captured]]
    ) -> tuple[Document | None, Captured | None]:
        """The document of ``key`` at ``revision``, computed by one request while the others wait.

        :returns: the document (``None`` if the answer is not one: an error, not JSON) and, for
            the request that computed it, its captured answer (``None`` for those that waited).
        """
        waiting = self._inflight.get((key, revision))
        if waiting is not None:
            return await asyncio.shield(waiting), None
        future: asyncio.Future[Document | None] = asyncio.get_running_loop().create_future()
        self._inflight[(key, revision)] = future
        try:
            captured = await compute()
            doc = captured.document(revision)
            if doc is not None:
                self.put(key, doc)
            future.set_result(doc)
            return doc, captured
        except BaseException:
            future.set_result(None)
            raise
        finally:
            del self._inflight[(key, revision)]

    def __len__(self) -> int:
        return len(self._docs)

    def close(self) -> None:
        """Forget every answer and close the revision source."""
        self._docs.clear()
        self._bytes = 0
        self.revision.close()


def _header(scope: Scope, name: bytes) -> str | None:
    for k, v in scope.get("headers", []):
        if k.lower() == name:
            return str(v.decode("latin-1"))
    return None


def _bearer(scope: Scope) -> str | None:
    scheme, _, secret = (_header(scope, b"authorization") or "").partition(" ")
    return secret.strip() or None if scheme.lower() == "bearer" else None


async def _may_read(auth: Authenticator, secret: str | None) -> bool:
    """``secret`` may read (as :func:`api.deps.require_viewer` decides); a database token is
    looked up in a worker thread."""
    try:
        if secret is None or auth.is_env_secret(secret):
            auth.require(secret, Role.VIEWER)
        else:
            await anyio.to_thread.run_sync(auth.require, secret, Role.VIEWER)
    except AuthError:
        return False
    return True


async def _answer(send: Send, doc: Document, if_none_match: str | None) -> None:
    headers = [(b"etag", doc.etag.encode("latin-1")), (b"cache-control", CACHE_CONTROL)]
    if matches(if_none_match, doc.etag):
        await send({"type": "http.response.start", "status": 304, "headers": headers})
        await send({"type": "http.response.body", "body": b""})
        return
    headers += [(b"content-type", doc.content_type), (b"content-length", str(len(doc.body)).encode())]
    await send({"type": "http.response.start", "status": 200, "headers": headers})
    await send({"type": "http.response.body", "body": doc.body})


class Captured:
    """The messages of one answer of the app, held back until it is complete."""

    def __init__(self) -> None:
        self.start: Message | None = None
        self.chunks: list[bytes] = []

    async def send(self, message: Message) -> None:
        if message["type"] == "http.response.start":
            self.start = message
        elif message["type"] == "http.response.body":
            self.chunks.append(bytes(message.get("body", b"")))

    def document(self, revision: Revision | None) -> Document | None:
        """The answer as a document if it is a ``200`` JSON one."""
        if self.start is None or self.start["status"] != 200:
            return None
        headers = {k.lower(): v for k, v in self.start.get("headers", [])}
        content_type = headers.get(b"content-type", b"")
        if not content_type.startswith(b"application/json"):
            return None
        body = b"".join(self.chunks)
        return Document(revision, etag_of(body), content_type, body, time.monotonic())

    async def replay(self, send: Send) -> None:
        if self.start is not None:
            await send(self.start)
        await send({"type": "http.response.body", "body": b"".join(self.chunks)})


class DocumentCache:
    """ASGI middleware answering the dashboard's documents from :class:`DocumentStore` (see the
    module docstring). The store and the authenticator are the running service's
    (``app.state.services``); without them every request goes on to the app unchanged."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        path = scope.get("path", "") if scope["type"] == "http" and scope.get("method") == "GET" else ""
        services = getattr(getattr(scope.get("app"), "state", None), "services", None)
        store: DocumentStore | None = getattr(services, "documents", None)
        health = path == HEALTH_PATH
        if not (health or KEPT.match(path)) or services is None or store is None:
            await self.app(scope, receive, send)
            return
        if not health and not await _may_read(services.auth, _bearer(scope)):
            await self.app(scope, receive, send)  # the route answers 401/403
            return
        if_none_match = _header(scope, b"if-none-match")
        revision = await store.revision.current()
        if revision is None:
            fresh = await self._compute(scope, receive)
            doc = fresh.document(None)
            await (_answer(send, doc, if_none_match) if doc is not None else fresh.replay(send))
            return
        key = path + "?" + scope.get("query_string", b"").decode("latin-1")
        doc = store.get(key, revision, HEALTH_MAX_AGE_S if health else None)
        if doc is None:
            doc, captured = await store.once(key, revision, lambda: self._compute(scope, receive))
            if doc is None:  # not a document (an error): its own answer, or, if waited for, our own
                await (captured or await self._compute(scope, receive)).replay(send)
                return
        await _answer(send, doc, if_none_match)

    async def _compute(self, scope: Scope, receive: Receive) -> Captured:
        captured = Captured()
        await self.app(scope, receive, captured.send)
        return captured
