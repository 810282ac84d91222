"""A blocking device call under a wall-clock deadline.

A table driver call may block (a move that waits for "in position", a port that no longer
answers). The sequencer runs such a call in a helper thread and gives up after a deadline,
so a device that stops answering ends the run with :class:`DeviceTimeout` instead of hanging
it; while it waits it may keep doing its own work (draining the DAQ) through ``wait``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TypeVar

from drivers.errors import DeviceTimeout

T = TypeVar("T")


def call_with_deadline(
    fn: Callable[[], T], deadline_s: float, what: str, wait: Callable[[], None] | None = None
) -> T:
    """Run ``fn()`` in a helper thread; return its value or re-raise its exception.

    :param deadline_s: wall-clock limit (s) on the call.
    :param what: the call's name in the timeout message (``"table {what} did not return …"``).
    :param wait: called repeatedly while ``fn`` runs (it should return within a few tens of
        ms, e.g. handle one DAQ block); ``None`` just waits.
    :raises DeviceTimeout: ``fn`` did not return within ``deadline_s``; the helper thread is
        a daemon and is left to finish or die with the process.
    """
    values: list[T] = []
    errors: list[BaseException] = []

    def target() -> None:
        try:
            values.append(fn())
        except BaseException as exc:
            errors.append(exc)

    worker = threading.Thread(target=target, name=f"table-{what}", daemon=True)
    worker.start()
    end = time.monotonic() + deadline_s
    if wait is None:
        worker.join(deadline_s)
    else:
        while worker.is_alive() and time.monotonic() <= end:
            wait()
    if worker.is_alive():
        raise DeviceTimeout(f"table {what} did not return within {deadline_s:.3g} s")
    if errors:
        raise errors[0]
    return values[0]
