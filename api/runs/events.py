"""A run's live events as the database holds them, for the event streams of any API process.

The bench's agent writes a run's state, its latest progress (``Run.live_progress``,
:class:`station.runs.live.DbLiveObserver`), each complete window (``run_window``) and, once the
results and certificate are stored, its final event (``Run.final_event``).
:func:`run_snapshot` reads them in one short read-only transaction; the stream of
``GET /api/runs/{id}/events`` turns the differences between two snapshots into events. No
in-process hub is needed, so every API worker streams every run, including after the
process restarted mid-run. On PostgreSQL a notification (:mod:`db.notify`,
:mod:`api.runs.wakeup`) wakes the streams of a run as soon as a write to it commits.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import threading
import time
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from api.runs.wakeup import EVENT_POLL_S
from db.models import FINAL_STATES, Run, RunState, RunWindow
from db.repo.gaps import list_gaps
from db.repo.recovery import DEFAULT_STALE_AFTER_S
from db.types import utc_now
from station.runs.live import window_means


@dataclasses.dataclass(frozen=True)
class RunSnapshot:
    """What a stream needs of a run at one moment.

    :param windows: ``window`` events of the windows completed after the caller's last one.
    :param last_window: index of the run's last complete window (``None``: none yet).
    :param live: the latest ``progress`` event's data, if the agent stored one.
    :param finished: the final event's data once the run is over and its results stored.
    :param gaps: ``gap`` events: every sample gap recorded so far (the run's ``sample_gap`` rows).
    """

    state: RunState
    error: str | None
    live: dict[str, Any] | None
    windows: tuple[dict[str, Any], ...]
    last_window: int | None
    finished: dict[str, Any] | None
    gaps: tuple[dict[str, Any], ...] = ()


def _finished(run: Run, now: dt.datetime) -> dict[str, Any] | None:
    stored = run.final_event
    if isinstance(stored, dict) and stored and run.state in (*FINAL_STATES, RunState.INTERRUPTED):
        return stored
    plain = {"state": run.state.value, "outcome": run.outcome, "error": run.error}
    if run.state is RunState.INTERRUPTED:
        return plain
    if run.state not in FINAL_STATES:
        return None
    if run.kind is None:  # not a service run: nothing more will be stored
        return plain
    ended = run.finished_at or run.heartbeat_at
    if ended is not None and (now - ended).total_seconds() > DEFAULT_STALE_AFTER_S:
        return plain  # its agent died while storing the results
    return None


def run_snapshot(
    sessions: sessionmaker[Session], run_id: str, after_window: int | None
) -> RunSnapshot | None:
    """The run's snapshot, ``None`` if there is no such run.

    :param after_window: list the windows with a greater index (-1: all); ``None``: list none
        (a stream that starts mid-run does not replay the past).
    """
    with sessions.begin() as s:
        run = s.get(Run, run_id)
        if run is None:
            return None
        windows: list[dict[str, Any]] = []
        if after_window is not None:
            rows = s.scalars(
                sa.select(RunWindow)
                .where(RunWindow.run_id == run_id, RunWindow.index > after_window)
                .order_by(RunWindow.index)
            )
            windows = [
                {
                    "index": w.index,
                    "label": w.label,
                    "kind": w.kind,
                    "pose_deg": list(w.pose_deg),
                    "n_samples": w.n_samples,
                    "means": window_means(w.means),
                }
                for w in rows
            ]
        live = run.live_progress
        last = windows[-1]["index"] if windows else run.last_complete_window
        if after_window is not None and last is not None and last < after_window:
            last = after_window  # a resumed run re-records from an earlier window
        return RunSnapshot(
            run.state,
            run.error,
            live if isinstance(live, dict) else None,
            tuple(windows),
            last,
            _finished(run, utc_now()),
            tuple(dataclasses.asdict(g) for g in list_gaps(s, run_id)),
        )


class SnapshotCache:
    """One database read per run per ``max_age_s`` for all the event streams of a process.

    Every open stream of a run asks for its snapshot every :data:`EVENT_POLL_S`; fifty
    streams would make fifty reads. The first ask after ``max_age_s`` reads the run (with all
    its windows) and the others reuse that snapshot, each taking the windows it has not sent.
    A notified change drops the run's snapshot (:meth:`invalidate`), so the next ask reads.
    """

    def __init__(self, sessions: sessionmaker[Session], max_age_s: float = EVENT_POLL_S / 2) -> None:
        self.sessions, self.max_age_s = sessions, max_age_s
        self._lock = threading.Lock()
        self._cache: dict[str, tuple[float, RunSnapshot | None]] = {}

    def get(self, run_id: str) -> RunSnapshot | None:
        """The run's snapshot with every complete window, at most ``max_age_s`` old."""
        with self._lock:
            now = time.monotonic()
            hit = self._cache.get(run_id)
            if hit is not None and now - hit[0] < self.max_age_s:
                return hit[1]
            snap = run_snapshot(self.sessions, run_id, -1)
            for key in [k for k, (t, _) in self._cache.items() if now - t > 60.0]:
                del self._cache[key]
            self._cache[run_id] = (now, snap)
            return snap

    def invalidate(self, run_id: str) -> None:
        """Forget the run's snapshot (it changed): the next :meth:`get` reads the database."""
        with self._lock:
            self._cache.pop(run_id, None)
