"""Nightly drift checks: re-measure every certified unit of the lab and compare with its last
certificate (the test itself: :mod:`bench.uncertainty.drift`).

:class:`DriftScheduler` runs once a day at ``CALBENCH_DRIFT_TIME`` (``HH:MM``, local time of
the clock): it queues a drift check for every unit that has a certificate, on the unit's own
bench (:mod:`station.drift.plan`), where that bench's agent runs the checks one after the other.
A unit whose bench has no live agent, or whose agent cannot run the check's procedure, is not
checked: it is logged and listed with the reason (:attr:`DriftScheduler.not_checked`,
``GET /api/drift``). Every API process runs a scheduler; the run queue keeps one check per unit
a night (:meth:`station.runs.queue.RunQueue.start`, ``drift_night``). Its clock is injectable and
:meth:`DriftScheduler.tick` is what its thread calls, so tests drive it without waiting for
the night.
"""

from __future__ import annotations

import datetime as dt
import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from sqlalchemy.orm import Session, sessionmaker

from bench.records import utc_now
from db.repo.benches import bench_status
from db.repo.units import get_unit_by_serial
from station.drift.plan import DueUnit, NotChecked, plan_checks
from station.drift.record import unit_bench, units_due
from station.settings import Settings

if TYPE_CHECKING:
    from station.runs.queue import RunQueue

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
    """Queues the nightly check runs, each on its unit's bench.

    :param clock: wall clock (aware datetime); the run time is taken in the clock's local zone.
    :param poll_s: how often the thread calls :meth:`tick`.
    :ivar not_checked: the units the last queueing left unchecked, by serial, with the reason.
    """

    def __init__(
        self,
        settings: Settings,
        sessions: sessionmaker[Session],
        runner: RunQueue,
        clock: Callable[[], dt.datetime] = utc_now,
        poll_s: float = 20.0,
    ) -> None:
        self.settings, self.sessions, self.runner, self.clock = settings, sessions, runner, clock
        self.time_of_day = parse_time_of_day(settings.drift_time)
        self.poll_s = poll_s
        self.not_checked: dict[str, NotChecked] = {}
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

    def enqueue(self, serial: str | None = None, *, night: dt.datetime | None = None) -> list[str]:
        """Queue the drift check of one unit (it must exist) or of every unit with a certificate,
        each on its bench; returns the ids of the runs queued (or queued already: the unit's
        check waiting or running, or this ``night``'s). The units left unchecked replace
        :attr:`not_checked` (one unit: its entry only) and are logged.

        :param night: the scheduled time of the night the checks are for (``None``: asked now).
        :raises LookupError: the unit is unknown.
        """
        procedure = self.settings.drift_procedure
        with self.sessions.begin() as s:
            if serial is not None:
                unit = get_unit_by_serial(s, serial)
                if unit is None:
                    raise LookupError(f"unit {serial} not found")
                due = [DueUnit(serial, unit_bench(s, unit))]
            else:
                due = units_due(s)
            targets, skipped = plan_checks(due, bench_status(s), procedure)
        ids: list[str] = []
        for target in targets:
            try:
                live = self.runner.start(
                    target.unit_serial,
                    procedure,
                    dwell_s=self.settings.drift_dwell_s,
                    kind="drift_check",
                    bench=target.bench,
                    drift_night=night.isoformat() if night is not None else None,
                )
            except ValueError as exc:  # UnknownBench: the bench changed since the plan
                skipped.append(NotChecked(target.unit_serial, target.bench, str(exc)))
                continue
            ids.append(live.id)
        for item in skipped:
            log.warning(
                "drift check of %s not queued (bench %s): %s", item.unit_serial, item.bench, item.reason
            )
        with self._lock:
            if serial is None:
                self.not_checked = {}
            else:
                self.not_checked.pop(serial, None)
            self.not_checked.update({item.unit_serial: item for item in skipped})
            self.last_run_at = self.clock()
        return ids

    def tick(self) -> str | None:
        """Queue the night's checks when their time has come; returns the id of the first run
        queued then, if any (the benches' agents run them)."""
        now = self.clock()
        if self.next_run_at is None or now < self.next_run_at:
            return None
        night, self.next_run_at = self.next_run_at, self._next_after(now)
        ids = self.enqueue(night=night)
        return ids[0] if ids else None

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
        """Stop the thread (the checks queued stay queued for their benches' agents)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
