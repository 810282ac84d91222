"""Wake-ups of a process's event streams when a run changes in the database.

Each open ``/api/runs/{id}/events`` stream holds a :class:`Waiter`; between two reads of the
run it waits on it for at most :attr:`RunWakeups.poll_s`. On PostgreSQL the process's
:class:`db.notify.RunListener` calls :meth:`RunWakeups.notify` with the id of every run a
committed transaction changed (in any process: the bench's agent, another API worker), and the
streams of that run wake at once and read it afresh. While the listener is not listening
(SQLite, or the connection is lost) the streams poll every :data:`EVENT_POLL_S`; while it is,
they still read every :data:`FALLBACK_POLL_S`, in case a notification was lost.
"""

from __future__ import annotations

import asyncio
import threading
from collections import defaultdict
from collections.abc import Callable

EVENT_POLL_S = 0.5
"""Poll period of an event stream without notifications (SQLite, listener down), s."""
FALLBACK_POLL_S = 10.0
"""Poll period of an event stream while notifications arrive (PostgreSQL LISTEN), s."""


class Waiter:
    """One stream's wake-up flag for one run, on the stream's event loop."""

    def __init__(self, run_id: str, loop: asyncio.AbstractEventLoop) -> None:
        self.run_id, self.loop = run_id, loop
        self.event = asyncio.Event()

    async def wait(self, timeout_s: float) -> bool:
        """Wait until the run is notified or ``timeout_s`` passes; True if notified. A notification
        that came since the last wait counts (none is lost between a read and the wait)."""
        if self.event.is_set():
            self.event.clear()
            return True
        try:
            await asyncio.wait_for(self.event.wait(), timeout_s)
        except TimeoutError:
            return False
        finally:
            self.event.clear()
        return True


class RunWakeups:
    """Thread-safe registry of the waiters of each run.

    :param on_notify: called with the run id before the waiters wake (the snapshot cache drops
        the run's cached read there, so the woken streams read the new state).
    """

    def __init__(self, on_notify: Callable[[str], None] = lambda _run_id: None) -> None:
        self.on_notify = on_notify
        self._lock = threading.Lock()
        self._waiters: dict[str, set[Waiter]] = defaultdict(set)
        self._listening = False

    @property
    def listening(self) -> bool:
        """Notifications arrive (a listener is connected)."""
        return self._listening

    def set_listening(self, up: bool) -> None:
        """Called by the listener when ``LISTEN`` is in place (True) or its connection is lost;
        on a loss every waiter wakes, so the streams read and go back to short polls."""
        self._listening = up
        if not up:
            self.wake_all()

    def wake_all(self) -> None:
        """Wake every waiter (the service is stopping, or notifications stopped arriving)."""
        with self._lock:
            waiters = [w for group in self._waiters.values() for w in group]
        for w in waiters:
            self._wake(w)

    @property
    def poll_s(self) -> float:
        """How long a stream waits for a notification before it reads the run anyway (s)."""
        return FALLBACK_POLL_S if self._listening else EVENT_POLL_S

    def subscribe(self, run_id: str) -> Waiter:
        """A waiter for ``run_id`` on the running loop (subscribe before the first read)."""
        waiter = Waiter(run_id, asyncio.get_running_loop())
        with self._lock:
            self._waiters[run_id].add(waiter)
        return waiter

    def unsubscribe(self, waiter: Waiter) -> None:
        """Forget ``waiter``."""
        with self._lock:
            group = self._waiters.get(waiter.run_id)
            if group is not None:
                group.discard(waiter)
                if not group:
                    del self._waiters[waiter.run_id]

    def notify(self, run_id: str) -> None:
        """Run ``run_id`` changed: wake its waiters (callable from any thread)."""
        self.on_notify(run_id)
        with self._lock:
            waiters = list(self._waiters.get(run_id, ()))
        for w in waiters:
            self._wake(w)

    def n_waiters(self, run_id: str) -> int:
        """Open streams waiting on ``run_id``."""
        with self._lock:
            return len(self._waiters.get(run_id, ()))

    def _wake(self, waiter: Waiter) -> None:
        try:
            waiter.loop.call_soon_threadsafe(waiter.event.set)
        except RuntimeError:  # its loop is closed: the stream went away
            self.unsubscribe(waiter)
