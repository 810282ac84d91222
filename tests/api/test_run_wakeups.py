"""Event streams woken by run notifications: the waiters, and a stream that reads at once when
notified instead of after its poll period."""

from __future__ import annotations

import asyncio
import threading
import time
from typing import Any

import pytest

from api.runs.events import RunSnapshot
from api.runs.stream import run_events
from api.runs.wakeup import EVENT_POLL_S, FALLBACK_POLL_S, RunWakeups
from bench.run_state import RunState

LONG_S = 60.0
"""A poll period no test waits out: a stream that returns before it was woken."""


def _snap(
    state: RunState = RunState.RUNNING, live: dict[str, Any] | None = None, finished: bool = False
) -> RunSnapshot:
    return RunSnapshot(
        state=state,
        error=None,
        live=live,
        windows=(),
        last_window=None,
        finished={"state": "completed"} if finished else None,
    )


def test_a_notification_from_another_thread_wakes_only_that_runs_waiter() -> None:
    notified: list[str] = []
    wakeups = RunWakeups(on_notify=notified.append)

    async def main() -> tuple[bool, bool, float]:
        a, b = wakeups.subscribe("A"), wakeups.subscribe("B")
        t0 = time.monotonic()
        threading.Timer(0.05, wakeups.notify, args=("A",)).start()
        woke_a = await a.wait(LONG_S)
        elapsed = time.monotonic() - t0
        woke_b = await b.wait(0.05)
        return woke_a, woke_b, elapsed

    woke_a, woke_b, elapsed = asyncio.run(main())
    assert woke_a and not woke_b
    assert elapsed < LONG_S / 4
    assert notified == ["A"]


def test_a_notification_before_the_wait_is_not_lost_and_counts_once() -> None:
    wakeups = RunWakeups()

    async def main() -> tuple[bool, bool]:
        w = wakeups.subscribe("A")
        wakeups.notify("A")  # arrives while the stream is still reading
        await asyncio.sleep(0)  # the loop runs the threadsafe callback
        return await w.wait(LONG_S), await w.wait(0.01)

    assert asyncio.run(main()) == (True, False)


def test_an_unsubscribed_waiter_is_forgotten() -> None:
    wakeups = RunWakeups()

    async def main() -> int:
        w = wakeups.subscribe("A")
        assert wakeups.n_waiters("A") == 1
        wakeups.unsubscribe(w)
        wakeups.notify("A")
        return wakeups.n_waiters("A")

    assert asyncio.run(main()) == 0


def test_poll_period_is_long_only_while_listening_and_a_lost_listener_wakes_everyone() -> None:
    wakeups = RunWakeups()
    assert wakeups.poll_s == EVENT_POLL_S
    wakeups.set_listening(True)
    assert wakeups.poll_s == FALLBACK_POLL_S > 10 * EVENT_POLL_S

    async def main() -> bool:
        w = wakeups.subscribe("A")
        threading.Timer(0.05, wakeups.set_listening, args=(False,)).start()
        return await w.wait(LONG_S)

    assert asyncio.run(main())
    assert wakeups.poll_s == EVENT_POLL_S


def _collect(wakeups: RunWakeups, snaps: list[RunSnapshot], notify_after_s: float) -> tuple[list[str], float]:
    """Run a stream over ``snaps`` (first, then one per read) with a poll period of
    :data:`LONG_S`, notifying its run ``notify_after_s`` after each read; the event names
    and the wall time it took."""
    reads = iter(snaps[1:])

    async def read() -> RunSnapshot | None:
        threading.Timer(notify_after_s, wakeups.notify, args=("R",)).start()
        return next(reads, None)

    async def yes() -> bool:
        return True

    async def no() -> bool:
        return False

    async def main() -> list[str]:
        waiter = wakeups.subscribe("R")
        threading.Timer(notify_after_s, wakeups.notify, args=("R",)).start()
        out = []
        async for chunk in run_events(
            snaps[0],
            read=read,
            waiter=waiter,
            poll_s=lambda: LONG_S,
            closed=lambda: None,
            token_live=yes,
            disconnected=no,
        ):
            out.append(chunk.split("\n", 1)[0].removeprefix("event: "))
        return out

    t0 = time.monotonic()
    names = asyncio.run(main())
    return names, time.monotonic() - t0


def test_a_notified_stream_reads_at_once_instead_of_after_its_poll_period() -> None:
    snaps = [
        _snap(),
        _snap(live={"progress": 0.5}),
        _snap(live={"progress": 1.0}),
        _snap(RunState.COMPLETED, finished=True),
    ]
    names, elapsed = _collect(RunWakeups(), snaps, notify_after_s=0.05)
    assert names == ["state", "progress", "progress", "state", "finished"]
    assert elapsed < LONG_S / 4  # three waits, each ended by its notification


def test_a_stream_ends_with_shutdown_when_the_service_stops_while_it_waits() -> None:
    wakeups = RunWakeups()
    closed: list[str] = []

    async def never() -> RunSnapshot | None:
        pytest.fail("no read expected: nothing was notified and the poll period is long")

    async def yes() -> bool:
        return True

    async def main() -> list[str]:
        waiter = wakeups.subscribe("R")

        def stop() -> None:
            closed.append("the service is stopping")
            wakeups.wake_all()

        threading.Timer(0.05, stop).start()
        return [
            chunk
            async for chunk in run_events(
                _snap(),
                read=never,
                waiter=waiter,
                poll_s=lambda: LONG_S,
                closed=lambda: closed[0] if closed else None,
                token_live=yes,
                disconnected=yes,
            )
        ]

    t0 = time.monotonic()
    chunks = asyncio.run(main())
    assert time.monotonic() - t0 < LONG_S / 4
    assert [c.split("\n", 1)[0] for c in chunks] == ["event: state", "event: shutdown"]
    assert "the service is stopping" in chunks[-1]
