"""A number that changes whenever anything is committed to the database, cheap to read.

On SQLite it is ``PRAGMA data_version`` read on a connection of its own that never writes: the
value changes when any other connection, of this process or another (the bench's agent), has
committed since the last read (https://www.sqlite.org/pragma.html#pragma_data_version). One
read takes a few microseconds and waits for no lock (``busy_timeout`` 0: a busy database gives
``None``, "unknown", never a wait), so it may be read on the event loop.

Other backends have no such number here: :meth:`DatabaseRevision.current` is ``None`` there,
and whoever keys a cache on it computes every answer afresh.
"""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path

from sqlalchemy.engine import URL


class DatabaseRevision:
    """The database's revision: equal values mean nothing was committed in between.

    :param url: the database URL; only a file SQLite database has a revision.
    """

    def __init__(self, url: URL) -> None:
        self._lock = threading.Lock()
        self._conn: sqlite3.Connection | None = None
        database = url.database or ""
        if url.get_backend_name() == "sqlite" and database and Path(database).exists():
            conn = sqlite3.connect(database, isolation_level=None, check_same_thread=False)
            conn.execute("PRAGMA busy_timeout = 0")
            conn.execute("PRAGMA query_only = ON")
            self._conn = conn

    def current(self) -> int | None:
        """The revision now, or ``None`` when it cannot be told (no SQLite, busy, closed)."""
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
