"""Nightly drift checks: re-measure each unit of this bench and compare with its last certificate
(the test itself: :mod:`bench.uncertainty.drift`).

:class:`DriftScheduler` runs the check once a day at ``CALBENCH_DRIFT_TIME`` (``HH:MM``,
local time of the clock) for every unit of the bench that has a certificate, one after
the other on the bench's runner. Its clock is injectable and :meth:`DriftScheduler.tick`
is what its thread calls, so tests drive it without waiting for the night.
"""

from __future__ import annotations

import datetime as dt
import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from sqlalchemy.orm import Session, sessionmaker

from api.drift.record import units_due
from api.runs.runner import BenchBusy, BenchRunner
from api.settings import Settings
from bench.records import utc_now
from db.repo.units import get_unit_by_serial

if TYPE_CHECKING:
    from api.runs.queue import RunQueue

log = logging.getLogger(__name__)


def parse_time_of_day(text: str) -> dt.time | None:
    """``"HH:MM"`` -> ``time``; empty -> ``None`` (scheduler off).

    :raises ValueError: anything else, naming the setting.
    """
    if not text.strip():
        return None
    try:
        hh, mm = text.strip().split(":")
        return dt.time(int(hh), int(mm))
    except ValueError:
        raise ValueError(f"CALBENCH_DRIFT_TIME={text!r}: expected HH:MM (00:00..23:59) or empty") from None


class DriftScheduler:
    """Starts the nightly check runs on the runner, one unit at a time.

    :param clock: wall clock (aware datetime); the run time is taken in the clock's local zone.
    :param poll_s: how often the thread calls :meth:`tick`.
    """

    def __init__(
        self,
        settings: Settings,
        sessions: sessionmaker[Session],
        runner: BenchRunner | RunQueue,
        clock: Callable[[], dt.datetime] = utc_now,
        poll_s: float = 20.0,
    ) -> None:
        self.settings, self.sessions, self.runner, self.clock = settings, sessions, runner, clock
        self.time_of_day = parse_time_of_day(settings.drift_time)
        self.poll_s = poll_s
        self.pending: list[str] = []
        self.last_run_at: dt.datetime | None = None
        self.next_run_at = self._next_after(clock()) if self.time_of_day else None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _next_after(self, now: dt.datetime) -> dt.datetime:
        assert self.time_of_day is not None
        local = now.astimezone()
        tod = self.time_of_day
        at = local.replace(hour=tod.hour, minute=tod.minute, second=0, microsecond=0)
        return at if at > local else at + dt.timedelta(days=1)

    def enqueue(self, serial: str | None = None) -> list[str]:
        """Queue one unit (it must exist) or every due unit of the bench; returns the queue.

        :raises LookupError: the unit is unknown.
        """
        with self.sessions.begin() as s:
            if serial is not None and get_unit_by_serial(s, serial) is None:
                raise LookupError(f"unit {serial} not found")
            serials = [serial] if serial is not None else units_due(s, self.settings.bench_name)
        with self._lock:
            self.pending.extend(x for x in serials if x not in self.pending)
            self.last_run_at = self.clock()
            return list(self.pending)

    def tick(self) -> str | None:
        """Queue the units when the time has come, and start the next check if the bench is
        free; returns the id of the run started, if any."""
        now = self.clock()
        if self.next_run_at is not None and now >= self.next_run_at:
            self.next_run_at = self._next_after(now)
            self.enqueue()
        with self._lock:
            if not self.pending or self.runner.current is not None:
                return None
            serial = self.pending[0]
        try:
            live = self.runner.start(
                serial, self.settings.drift_procedure, dwell_s=self.settings.drift_dwell_s, kind="drift_check"
            )
        except BenchBusy:
            return None
        with self._lock:
            if serial in self.pending:
                self.pending.remove(serial)
        return live.id

    def _loop(self) -> None:
        while not self._stop.wait(self.poll_s):
            try:
                self.tick()
            except Exception:  # keep the scheduler alive; the next tick tries again
                log.exception("drift scheduler tick failed")

    def start(self) -> None:
        """Start the scheduler's thread."""
        self._thread = threading.Thread(target=self._loop, name="drift-scheduler", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the thread (the current check run, if any, is the runner's)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
