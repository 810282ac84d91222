"""A value that changes whenever anything is committed to the database, cheap to read.

:class:`DatabaseRevision` picks the reader of the database's backend:

- SQLite, :class:`SqliteDataVersion`: ``PRAGMA data_version`` read on a connection of its own
  that never writes: the value changes when any other connection, of this process or another
  (the bench's agent), has committed since the last read
  (https://www.sqlite.org/pragma.html#pragma_data_version). One read takes a few microseconds
  and waits for no lock (``busy_timeout`` 0: a busy database gives ``None``, "unknown", never a
  wait), so it is read on the event loop.
- PostgreSQL, :class:`api.pg_revision.SnapshotRevision`: the server's current snapshot
  (``pg_current_snapshot()``), read asynchronously on a connection of its own, one round trip
  shared by the requests that arrive while the previous one is under way.

Equal values mean nothing was committed in between, and a value is read before the document
kept with it is computed, which therefore shows at least what the value counts. Any other
backend, or a reader that fails, gives ``None``: whoever keys a cache on it computes every
answer afresh.
"""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path

from sqlalchemy.engine import URL

from api.pg_revision import SnapshotRevision
from db.notify import listen_url

Revision = int | str
"""A revision: SQLite's ``data_version`` or PostgreSQL's snapshot text; only equality counts."""


class SqliteDataVersion:
    """``PRAGMA data_version`` of a file SQLite database, on a read-only connection of its own.

    :param database: the database file (it must exist).
    """

    def __init__(self, database: str) -> None:
        self._lock = threading.Lock()
        conn = sqlite3.connect(database, isolation_level=None, check_same_thread=False)
        conn.execute("PRAGMA busy_timeout = 0")
        conn.execute("PRAGMA query_only = ON")
        self._conn: sqlite3.Connection | None = conn

    def current(self) -> int | None:
        """The data version now, or ``None`` when it cannot be told (busy, closed)."""
        with self._lock:
            if self._conn is None:
                return None
            try:
                row = self._conn.execute("PRAGMA data_version").fetchone()
            except sqlite3.Error:
                return None
        return int(row[0])

    def close(self) -> None:
        """Close the connection; :meth:`current` is ``None`` from then on."""
        with self._lock:
            if self._conn is not None:
                self._conn.close()
                self._conn = None


class DatabaseRevision:
    """The database's revision: equal values mean nothing was committed in between.

    :param url: the database URL; a file SQLite database and PostgreSQL have a revision.
    """

    def __init__(self, url: URL) -> None:
        self.sqlite: SqliteDataVersion | None = None
        self.postgresql: SnapshotRevision | None = None
        database = url.database or ""
        if url.get_backend_name() == "sqlite" and database and Path(database).exists():
            self.sqlite = SqliteDataVersion(database)
        elif (conninfo := listen_url(url)) is not None:
            self.postgresql = SnapshotRevision(conninfo)

    async def current(self) -> Revision | None:
        """The revision now, or ``None`` when it cannot be told (another backend, an error, closed).
        On PostgreSQL the read is one round trip to the server, awaited on the running loop."""
        if self.sqlite is not None:
            return self.sqlite.current()
        if self.postgresql is not None:
            return await self.postgresql.current()
        return None

    def close(self) -> None:
        """Close the reader's connection; :meth:`current` is ``None`` from then on."""
        if self.sqlite is not None:
            self.sqlite.close()
        if self.postgresql is not None:
            self.postgresql.close()
