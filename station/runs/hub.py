"""Fan-out of run events from the bench's worker thread to server-sent-event subscribers.

The worker thread calls :meth:`ProgressHub.publish`; every subscriber (one per open
``/api/runs/{id}/events`` stream) owns an ``asyncio.Queue`` on the event loop and gets the
event through ``loop.call_soon_threadsafe``. A slow subscriber loses its oldest events
(its queue is bounded), never blocks the bench. The last event of each run is kept, so a
stream opened mid-run starts from where the run is.
"""

from __future__ import annotations

import asyncio
import threading
from collections import defaultdict
from typing import Any

QUEUE_SIZE = 256
TERMINAL_EVENT = "finished"
CLOSED_EVENT = "shutdown"
"""Sent to every open stream when the service shuts down; the stream ends after it."""


class Subscription:
    """One subscriber's queue of ``(event, data)`` pairs for one run."""

    def __init__(self, run_id: str, loop: asyncio.AbstractEventLoop) -> None:
        self.run_id = run_id
        self.loop = loop
        self.queue: asyncio.Queue[tuple[str, dict[str, Any]]] = asyncio.Queue(QUEUE_SIZE)

    def _put(self, item: tuple[str, dict[str, Any]]) -> None:
        if self.queue.full():
            self.queue.get_nowait()
        self.queue.put_nowait(item)


class ProgressHub:
    """Thread-safe publisher of run events to asyncio subscribers."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._subs: dict[str, list[Subscription]] = defaultdict(list)
        self._last: dict[str, tuple[str, dict[str, Any]]] = {}
        self._closed: str | None = None

    def subscribe(self, run_id: str) -> Subscription:
        """A new subscription on the running loop; it first receives the run's last event."""
        sub = Subscription(run_id, asyncio.get_running_loop())
        with self._lock:
            self._subs[run_id].append(sub)
            last = self._last.get(run_id)
        if last is not None:
            sub._put(last)
        return sub

    def unsubscribe(self, sub: Subscription) -> None:
        """Stop delivering to ``sub``."""
        with self._lock:
            subs = self._subs.get(sub.run_id, [])
            if sub in subs:
                subs.remove(sub)
            if not subs:
                self._subs.pop(sub.run_id, None)

    def publish(self, run_id: str, event: str, data: dict[str, Any]) -> None:
        """Deliver ``event`` to every subscriber of ``run_id`` (callable from any thread)."""
        item = (event, data)
        with self._lock:
            self._last[run_id] = item
            subs = list(self._subs.get(run_id, []))
        for sub in subs:
            try:
                sub.loop.call_soon_threadsafe(sub._put, item)
            except RuntimeError:  # the subscriber's loop is closed: it went away
                self.unsubscribe(sub)

    def close_all(self, reason: str) -> None:
        """End every open stream with a :data:`CLOSED_EVENT` (the service is shutting down, so
        the server need not wait for long-lived streams before stopping the run)."""
        with self._lock:
            self._closed = reason
            subs = [sub for group in self._subs.values() for sub in group]
        for sub in subs:
            try:
                sub.loop.call_soon_threadsafe(sub._put, (CLOSED_EVENT, {"reason": reason}))
            except RuntimeError:
                self.unsubscribe(sub)

    @property
    def closed(self) -> str | None:
        """Why the hub was closed (streams opened after it end at once), ``None`` while open."""
        return self._closed

    def last(self, run_id: str) -> tuple[str, dict[str, Any]] | None:
        """The last event published for ``run_id``."""
        with self._lock:
            return self._last.get(run_id)

    def n_subscribers(self, run_id: str) -> int:
        """Open streams on ``run_id``."""
        with self._lock:
            return len(self._subs.get(run_id, []))
