"""A full disk: how an error says so (:func:`is_disk_full`, also the service's 507), and how the
bench agent lives through it: said once, retried calmly, said when it clears.

While the disk (or the database's file system) is full every poll of the agent fails the same
way (``ENOSPC``, SQLite's ``database or disk is full``: :func:`is_disk_full`, which
:mod:`bench.sequencer.faults` decides, the run's own faults included).
:class:`DiskFullWatch` turns that into one log line when it starts, at most one every
:data:`DISK_FULL_LOG_INTERVAL_S` while it lasts (with the number of failed polls)
and one when a poll succeeds again — no traceback. Meanwhile the agent polls less often: the
wait doubles from the normal poll period up to :data:`MAX_WAIT_S`. A run recording at that
moment is not lost: its writer's ``ENOSPC``, or the database refusing its writes on the full
disk, is a device fault, the run is left ``interrupted`` at its last durable chunk and resumed
(:mod:`station.execution.fault_retry`).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

from bench.sequencer.faults import is_disk_full

__all__ = ["DISK_FULL_LOG_INTERVAL_S", "MAX_WAIT_S", "DiskFullWatch", "is_disk_full"]

DISK_FULL_LOG_INTERVAL_S = 60.0
"""A full disk is logged at most once per this interval (s), not at every refused write."""


MAX_WAIT_S = 5.0
"""Longest wait between two polls while the disk is full (s)."""


class DiskFullWatch:
    """The disk-full state of a polling loop and its log lines.

    :param log: where the lines go; :param what: the loop's name in them.
    :param clock: monotonic clock (s); tests move it.
    """

    def __init__(
        self, log: logging.Logger, what: str, *, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.log, self.what, self.clock = log, what, clock
        self.failures = 0  # polls failed on a full disk since it filled
        self._since = 0.0
        self._logged = -math.inf

    @property
    def full(self) -> bool:
        """The last poll failed because the disk is full."""
        return self.failures > 0

    def failed(self, exc: BaseException) -> bool:
        """A poll raised ``exc``: ``True`` if it says the disk is full (then logged at most once
        per interval, without traceback), ``False`` for any other error (the caller logs it)."""
        if not is_disk_full(exc):
            return False
        now = self.clock()
        if self.failures == 0:
            self._since = now
        self.failures += 1
        if now - self._logged >= DISK_FULL_LOG_INTERVAL_S:
            self._logged = now
            reason = str(getattr(exc, "orig", None) or exc).splitlines()[0][:200]
            self.log.error(
                "%s: disk full for %.0f s (%d polls refused): %s; retrying every %g s at most, "
                "not logged again for %g s",
                self.what, now - self._since, self.failures, reason, MAX_WAIT_S,
                DISK_FULL_LOG_INTERVAL_S,
            )  # fmt: skip
        return True

    def succeeded(self) -> None:
        """A poll succeeded: if the disk was full, say that it is no longer."""
        if self.failures:
            self.log.warning(
                "%s: the disk accepts writes again after %.0f s (%d polls refused)",
                self.what, self.clock() - self._since, self.failures,
            )  # fmt: skip
        self.failures = 0
        self._logged = -math.inf

    def wait_s(self, poll_s: float) -> float:
        """The wait before the next poll (s): ``poll_s`` normally; while the disk is full
        ``min(poll_s · 2^failures, MAX_WAIT_S)``."""
        if not self.failures:
            return poll_s
        return float(min(poll_s * 2.0 ** min(self.failures, 30), max(MAX_WAIT_S, poll_s)))
