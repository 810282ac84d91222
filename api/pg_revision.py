"""PostgreSQL's revision for the document cache: the server's current snapshot, ``pg_current_snapshot()``.

A snapshot ``xmin:xmax:xip_list`` says exactly which transactions are visible: those below
``xmax`` that are not in ``xip_list`` and committed. Two snapshots that are equal see the same
committed transactions, and a commit between them changes the second: a transaction that was
running at the first is in its ``xip_list`` and is not in the second's; one that got its id
after the first has an id ``>= xmax`` of the first, and once it has ended ``xmax`` (one past the
latest ended transaction) is above it. "The main use of these functions is to determine which
transactions were committed between two snapshots"
(https://www.postgresql.org/docs/current/functions-info.html#FUNCTIONS-PG-SNAPSHOT). Ids are
cluster-wide, so commits to other databases of the server, aborts and autovacuum's ``ANALYZE``
change it too: never stale, at times a needless recomputation. A transaction that writes
nothing has no id and changes nothing.

Why not the WAL position (``pg_current_wal_insert_lsn()``, ``…_lsn()``, ``…_flush_lsn()``): a
commit's WAL record is inserted, and with ``synchronous_commit`` on flushed and waited for by
synchronous standbys, *before* the transaction leaves the set of running ones and becomes
visible (PostgreSQL's ``ProcArrayEndTransaction``: "the transaction commit/abort must already be
reported to WAL and pg_xact"). A position read in that window already counts the commit, a
document computed just after does not show it, and it would be kept at that position until the
next commit. The snapshot is the visibility itself, so a document computed after the revision
is read shows at least what the revision counts. The ``pg_current_wal_*`` functions also fail
on a standby (during recovery); ``pg_current_snapshot()`` is available there, over the replayed
transactions (not exercised by the tests, which run on a primary).

:class:`SnapshotRevision` reads it on a connection of its own (psycopg, asynchronous, on the
service's event loop, autocommit, :data:`STATEMENT_TIMEOUT_MS`), one read at a time: requests
that arrive while a read is under way share the next one, which starts after they arrived (a
read that began before a request is never its answer). A read that fails or takes longer
than :data:`READ_TIMEOUT_S` gives ``None`` ("unknown": the cache computes afresh) and drops the
connection; a new one is opened in the background after a pause that doubles up to
:data:`RETRY_MAX_S`, and requests get ``None`` at once meanwhile, never waiting for a connect.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import psycopg

log = logging.getLogger(__name__)

QUERY = "SELECT pg_current_snapshot()::text"
STATEMENT_TIMEOUT_MS = 500
"""The server cancels a read that runs longer (ms)."""
READ_TIMEOUT_S = 1.0
"""The longest a request waits for a read, the connection's round trip included (s)."""
CONNECT_TIMEOUT_S = 2
"""libpq's ``connect_timeout`` (whole seconds; values below 2 count as 2)."""
RETRY_FIRST_S = 0.5
RETRY_MAX_S = 10.0
"""Pause before the first reconnection after a failure, and the longest one (s)."""
APPLICATION_NAME = "calbench-revision"
"""``application_name`` of the connection (as ``pg_stat_activity`` shows it)."""


class SnapshotRevision:
    """``pg_current_snapshot()`` as text, read on the running event loop (see the module docstring).

    :param conninfo: libpq connection string (:func:`db.notify.listen_url`).
    """

    def __init__(self, conninfo: str) -> None:
        self.conninfo = conninfo
        self._loop: asyncio.AbstractEventLoop | None = None
        self._conn: psycopg.AsyncConnection[Any] | None = None
        self._connecting: asyncio.Task[None] | None = None
        self._reader: asyncio.Task[None] | None = None
        self._next: asyncio.Future[str | None] | None = None
        self._retry_at = 0.0
        self._pause_s = RETRY_FIRST_S
        self._closed = False

    @property
    def connected(self) -> bool:
        """A connection is open (reads are answered by the server)."""
        return self._conn is not None and not self._conn.closed

    async def current(self) -> str | None:
        """The snapshot read after this call began, or ``None`` (no connection, an error, a timeout)."""
        loop = asyncio.get_running_loop()
        if self._closed:
            return None
        if loop is not self._loop:  # another loop (a new service loop): its own connection
            self._drop()
            self._loop = loop
        if not self.connected:
            self._connect_later()
            return None
        if self._next is None:
            self._next = loop.create_future()
        waiting = self._next
        if self._reader is None or self._reader.done():
            self._reader = loop.create_task(self._read_batches())
        try:
            async with asyncio.timeout(READ_TIMEOUT_S):
                return await asyncio.shield(waiting)
        except TimeoutError:
            return None

    async def _read_batches(self) -> None:
        """Read for each batch of waiting requests in turn, until none waits."""
        while self._next is not None:
            batch, self._next = self._next, None
            value = await self._read_once()
            if not batch.done():
                batch.set_result(value)

    async def _read_once(self) -> str | None:
        conn = self._conn
        if conn is None or conn.closed:
            return None
        try:
            async with asyncio.timeout(READ_TIMEOUT_S):
                cur = await conn.execute(QUERY)
                row = await cur.fetchone()
        except Exception as exc:  # lost, refused, cancelled by statement_timeout, too slow
            log.warning("database revision unknown: %s; reconnecting in %.1f s", exc, self._pause_s)
            self._failed()
            return None
        return None if row is None else str(row[0])

    def _connect_later(self) -> None:
        if self._connecting is not None and not self._connecting.done():
            return
        if time.monotonic() < self._retry_at:
            return
        self._connecting = asyncio.get_running_loop().create_task(self._connect())

    async def _connect(self) -> None:
        import psycopg

        try:
            async with asyncio.timeout(CONNECT_TIMEOUT_S + 1.0):
                conn = await psycopg.AsyncConnection.connect(
                    self.conninfo,
                    autocommit=True,
                    connect_timeout=CONNECT_TIMEOUT_S,
                    application_name=APPLICATION_NAME,
                    options=f"-c statement_timeout={STATEMENT_TIMEOUT_MS}",
                )
        except Exception as exc:
            log.warning("database revision: cannot connect (%s); retry in %.1f s", exc, self._pause_s)
            self._failed()
            return
        if self._closed:
            await conn.close()
            return
        self._conn = conn
        self._pause_s = RETRY_FIRST_S

    def _failed(self) -> None:
        """Drop the connection; the next one is opened after the pause, which doubles."""
        self._finish_conn()
        self._retry_at = time.monotonic() + self._pause_s
        self._pause_s = min(2.0 * self._pause_s, RETRY_MAX_S)

    def _finish_conn(self) -> None:
        conn, self._conn = self._conn, None
        if conn is not None:
            # what AsyncConnection.close() does, without an await (callable from any context)
            with contextlib.suppress(Exception):
                conn.pgconn.finish()

    def _drop(self) -> None:
        """Forget the connection and the reads of another loop."""
        self._finish_conn()
        for task in (self._connecting, self._reader):
            if task is not None and not task.done() and self._loop is not None and not self._loop.is_closed():
                self._loop.call_soon_threadsafe(task.cancel)
        self._connecting = self._reader = None
        self._next = None

    def close(self) -> None:
        """Close the connection; :meth:`current` is ``None`` from then on."""
        self._closed = True
        self._drop()
