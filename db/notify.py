"""Run-change notifications between processes: PostgreSQL ``NOTIFY``/``LISTEN``.

A process that writes what a run's event stream shows (state, latest progress, a window, a
sample gap, the final event) calls :func:`notify_run` in the same transaction; PostgreSQL
delivers ``NOTIFY calbench_run, '<run id>'`` to every listening connection when (and only
when) that transaction commits, so a listener that wakes and reads the run sees the write.
On SQLite :func:`notify_run` does nothing: readers poll.

:class:`RunListener` is one thread per API process holding one connection with
``LISTEN calbench_run``; it hands each notified run id to a callback. It reconnects after a
lost connection (with growing waits up to :data:`RECONNECT_MAX_S`) and says whether it is
listening now (:attr:`RunListener.listening`), so the readers can fall back to a short poll
period while it is not.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

import sqlalchemy as sa
from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session

log = logging.getLogger(__name__)

CHANNEL = "calbench_run"
"""The notification channel; the payload is the run id (at most 100 characters)."""
LISTENER_NAME = "calbench-listener"
"""``application_name`` of a listener's connection (as ``pg_stat_activity`` shows it)."""
RECONNECT_MAX_S = 10.0
"""Longest wait between two connection attempts of a listener (s)."""


def notify_run(session: Session, run_id: str) -> None:
    """Notify the listeners that run ``run_id`` changed, when the session's transaction commits
    (PostgreSQL; a no-op on SQLite). Notifications with one payload in one transaction are
    delivered once."""
    if session.get_bind().dialect.name == "postgresql":
        session.execute(sa.select(sa.func.pg_notify(CHANNEL, run_id)))


def listen_url(database_url: str | sa.URL) -> str | None:
    """The libpq connection string of a PostgreSQL SQLAlchemy URL (``postgresql+psycopg://…`` →
    ``postgresql://…``, password kept), ``None`` for any other backend (nothing to listen to)."""
    url = make_url(database_url)
    if url.get_backend_name() != "postgresql":
        return None
    return url.set(drivername="postgresql").render_as_string(hide_password=False)


class RunListener:
    """A thread that listens on :data:`CHANNEL` and calls ``on_run(run_id)`` for each notification.

    :param conninfo: libpq connection string (:func:`listen_url`).
    :param on_run: called in the listener's thread with the run id; must not block.
    :param on_listening: called with ``True`` once ``LISTEN`` is in place, ``False`` when the
        connection is lost (notifications sent meanwhile are lost: the readers poll then).
    :param wait_s: longest wait for a notification before the stop flag is checked again (s).
    """

    def __init__(
        self,
        conninfo: str,
        on_run: Callable[[str], None],
        on_listening: Callable[[bool], None] = lambda _up: None,
        wait_s: float = 1.0,
    ) -> None:
        self.conninfo, self.on_run, self.on_listening, self.wait_s = conninfo, on_run, on_listening, wait_s
        self._stop = threading.Event()
        self._up = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def listening(self) -> bool:
        """``LISTEN`` is in place on a live connection."""
        return self._up.is_set()

    def start(self) -> None:
        """Start listening in a daemon thread."""
        self._thread = threading.Thread(target=self._run, name="run-listener", daemon=True)
        self._thread.start()

    def wait_listening(self, timeout_s: float) -> bool:
        """Wait until ``LISTEN`` is in place; False on timeout."""
        return self._up.wait(timeout_s)

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the thread (it ends within ``wait_s``)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)

    def _set_up(self, up: bool) -> None:
        if up == self._up.is_set():
            return
        if up:
            self._up.set()
        else:
            self._up.clear()
        self.on_listening(up)

    def _run(self) -> None:
        pause = 0.5
        while not self._stop.is_set():
            try:
                self._listen()
                pause = 0.5
            except Exception as exc:  # connection refused or lost: poll meanwhile, try again
                self._set_up(False)
                log.warning("LISTEN %s: %s; polling until it is back (retry in %.1f s)", CHANNEL, exc, pause)
                self._stop.wait(pause)
                pause = min(2 * pause, RECONNECT_MAX_S)
        self._set_up(False)

    def _listen(self) -> None:
        import psycopg

        with psycopg.connect(
            self.conninfo, autocommit=True, connect_timeout=5, application_name=LISTENER_NAME
        ) as conn:
            conn.execute(f"LISTEN {CHANNEL}")
            self._set_up(True)
            while not self._stop.is_set():
                for note in conn.notifies(timeout=self.wait_s):
                    self.on_run(note.payload)
                    if self._stop.is_set():
                        break
                conn.execute("SELECT 1")  # a lost connection raises here, not only on the next notify
