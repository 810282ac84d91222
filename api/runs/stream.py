"""The server-sent events of one run, from the database's snapshots of it.

:func:`run_events` turns successive :class:`~api.runs.events.RunSnapshot` reads into
``gap``, ``state``, ``window``, ``progress`` and ``signal`` events (the decimated tail of the
signal the agent stores beside the progress, :data:`station.runs.live.SIGNAL_KEY`) and ends
with ``finished``. Between two
reads it waits on the run's :class:`~api.runs.wakeup.Waiter`: a notification (PostgreSQL
LISTEN) makes it read at once, otherwise it reads after the poll period. While it waits it
still ends the stream when the service stops (``shutdown``) or the token is revoked (checked
every :data:`REAUTH_S`), and sends a keep-alive comment after :data:`KEEPALIVE_S` of silence.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator, Awaitable, Callable, Mapping

from api.runs.events import RunSnapshot
from api.runs.wakeup import Waiter
from bench.run_state import RunState
from station.runs.hub import CLOSED_EVENT, TERMINAL_EVENT
from station.runs.live import SIGNAL_KEY

KEEPALIVE_S = 15.0
"""Silence after which a stream sends a keep-alive comment and checks the client is there (s)."""
REAUTH_S = 2.0
"""An open event stream checks this often (s) that its token has not been revoked."""


def sse(event: str, data: Mapping[str, object]) -> str:
    """One server-sent event: ``event: NAME`` and its JSON ``data`` line."""
    return f"event: {event}\ndata: {json.dumps(data, default=str)}\n\n"


async def run_events(
    first: RunSnapshot,
    *,
    read: Callable[[], Awaitable[RunSnapshot | None]],
    waiter: Waiter,
    poll_s: Callable[[], float],
    closed: Callable[[], str | None],
    token_live: Callable[[], Awaitable[bool]],
    disconnected: Callable[[], Awaitable[bool]],
) -> AsyncIterator[str]:
    """The run's events from ``first`` on (a stream opened mid-run does not replay past windows).

    :param read: the run's next snapshot (``None``: the run is gone, the stream ends).
    :param waiter: woken when the run changed; :param poll_s: the longest wait between reads (s).
    :param closed: why the service is stopping, ``None`` while it serves.
    :param token_live: the stream's token is still valid; :param disconnected: the client left.
    """
    loop = asyncio.get_running_loop()
    snap: RunSnapshot | None = first
    state: RunState | None = None
    live: dict[str, object] | None = None
    signal: dict[str, object] | None = None
    last_window = first.last_window
    n_gaps = 0  # every gap is news: the run page counts the lost samples from them
    last_read = last_sent = last_check = loop.time()
    while snap is not None:
        for gap in snap.gaps[n_gaps:]:
            yield sse("gap", gap)
            last_sent = loop.time()
        n_gaps = len(snap.gaps)
        if snap.state != state:
            state = snap.state
            yield sse("state", {"state": state.value, "reason": snap.error or ""})
            last_sent = loop.time()
        for window in snap.windows:
            if last_window is None or window["index"] > last_window:
                yield sse("window", window)
                last_window, last_sent = window["index"], loop.time()
        if snap.live is not None and snap.finished is None:
            progress = {k: v for k, v in snap.live.items() if k != SIGNAL_KEY}
            if progress != live:
                live = progress
                yield sse("progress", live)
                last_sent = loop.time()
            view = snap.live.get(SIGNAL_KEY)
            if isinstance(view, dict) and view != signal:
                signal = view
                yield sse("signal", view)
                last_sent = loop.time()
        if snap.finished is not None:
            yield sse(TERMINAL_EVENT, snap.finished)
            return
        notified = False
        while True:  # until a notification or the poll period says: read again
            reason = closed()
            if reason is not None:
                yield sse(CLOSED_EVENT, {"reason": reason})
                return
            now = loop.time()
            if notified or now >= last_read + poll_s():
                break
            if now - last_check >= REAUTH_S:
                last_check = now
                if not await token_live():
                    yield sse(CLOSED_EVENT, {"reason": "the token of this stream has been revoked"})
                    return
            if now - last_sent >= KEEPALIVE_S:
                if await disconnected():
                    return
                last_sent = now
                yield ": keepalive\n\n"
            due = min(last_read + poll_s(), last_check + REAUTH_S, last_sent + KEEPALIVE_S)
            notified = await waiter.wait(max(0.0, due - loop.time()))
        snap = await read()
        last_read = loop.time()
