"""The bench's runner: one worker thread at a time owns the bench and its sequencer.

:meth:`BenchRunner.start` validates the request, allocates the run id, and starts a worker
thread that calls :func:`api.bench_session.start_run` with a :class:`HubObserver` (progress
to the event streams) and then the finisher (fit, diagnosis, certificate or drift
comparison, in the database). A second start while a run holds the bench raises
:class:`BenchBusy` (HTTP 409). The simulated unit behind a serial is
``SensorTruth.typical(seed=crc32(serial)).aged(age_days)``, its age counted from the unit's
first registration on the runner's clock, so a sensor ages from day to day and tests can
move the clock.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
import threading
import zlib
from collections.abc import Callable
from typing import Any, Literal

from sqlalchemy.orm import Session, sessionmaker

from api.bench_session import start_run
from api.progress_hub import TERMINAL_EVENT, ProgressHub
from api.settings import Settings
from bench.procedures import build_procedure, preview
from bench.records import (
    NullObserver,
    Progress,
    RunRecord,
    RunStart,
    StateChange,
    WindowRecord,
    new_run_id,
    utc_now,
)
from bench.sequencer_control import RunControl, SequencerConfig
from db.repo.units import get_unit_by_serial
from drivers.sim.physics import SensorTruth

log = logging.getLogger(__name__)

RunKind = Literal["calibration", "drift_check"]
Finisher = Callable[["LiveRun", RunRecord], None]


class BenchBusy(Exception):
    """The bench is running another run (HTTP 409)."""

    def __init__(self, run_id: str) -> None:
        super().__init__(f"the bench is busy with run {run_id}; abort it or wait until it finishes")
        self.run_id = run_id


def unit_seed(serial: str) -> int:
    """Seed of a simulated unit: CRC-32 of its serial (stable across processes)."""
    return zlib.crc32(serial.encode("utf-8"))


def simulated_unit(serial: str, age_days: float) -> SensorTruth:
    """The simulated sensor with this serial, ``age_days`` after its first registration."""
    seed = unit_seed(serial)
    return SensorTruth.typical("V", seed).aged(max(0.0, age_days), seed)


@dataclasses.dataclass
class LiveRun:
    """What the runner knows of the run holding the bench (thread-safe enough: the worker
    writes plain attributes, readers take snapshots)."""

    id: str
    unit_serial: str
    procedure: str
    kind: RunKind
    control: RunControl
    age_days: float
    state: str = "queued"
    progress: float = 0.0
    created_at: dt.datetime = dataclasses.field(default_factory=utc_now)
    record: RunRecord | None = None
    error: str | None = None
    done: threading.Event = dataclasses.field(default_factory=threading.Event)
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)


class HubObserver(NullObserver):
    """Run observer that publishes state, progress and windows to the hub and the live run."""

    def __init__(self, live: LiveRun, hub: ProgressHub) -> None:
        self.live, self.hub = live, hub

    def on_start(self, start: RunStart) -> None:
        self.live.state = "running"
        self.hub.publish(self.live.id, "state", {"state": "running", "reason": "started"})

    def on_state(self, run_id: str, change: StateChange) -> None:
        self.live.state = change.state.value
        self.hub.publish(run_id, "state", {"state": change.state.value, "reason": change.reason})

    def on_progress(self, run_id: str, progress: Progress) -> None:
        self.live.state = "running" if progress.state.value == "running" else progress.state.value
        self.live.progress = progress.fraction
        self.hub.publish(
            run_id,
            "progress",
            {
                "progress": progress.fraction,
                "step_index": progress.step_index,
                "n_steps": progress.n_steps,
                "step_label": progress.step_label,
                "window_index": progress.window_index,
                "n_windows": progress.n_windows,
                "elapsed_s": progress.elapsed_s,
                "expected_total_s": progress.expected_total_s,
                "table_deg": list(progress.table_deg),
                "state": progress.state.value,
            },
        )

    def on_window(self, run_id: str, window: WindowRecord) -> None:
        self.hub.publish(
            run_id,
            "window",
            {"index": window.index, "label": window.label, "kind": window.kind.value,
             "pose_deg": list(window.pose_deg), "n_samples": window.n_samples},
        )


class BenchRunner:
    """Owns the bench: at most one run at a time, each in its own worker thread.

    :param settings: service settings (simulation, dwell, bench name).
    :param sessions: database session factory.
    :param hub: where progress events go.
    :param finisher: called in the worker after the run ended (stores results); its
        exceptions are logged and reported on the stream, the run's state stays as stored.
    :param clock: wall clock (UTC), replaceable in tests to age simulated units.
    """

    def __init__(
        self,
        settings: Settings,
        sessions: sessionmaker[Session],
        hub: ProgressHub,
        finisher: Finisher | None = None,
        clock: Callable[[], dt.datetime] = utc_now,
    ) -> None:
        self.settings, self.sessions, self.hub = settings, sessions, hub
        self.finisher = finisher
        self.clock = clock
        self._lock = threading.Lock()
        self._current: LiveRun | None = None
        self._thread: threading.Thread | None = None
        self._recent: dict[str, LiveRun] = {}

    @property
    def current(self) -> LiveRun | None:
        """The run holding the bench, if any."""
        return self._current

    def live(self, run_id: str) -> LiveRun | None:
        """The live (or recently finished) run with this id, as the runner knows it."""
        cur = self._current
        if cur is not None and cur.id == run_id:
            return cur
        return self._recent.get(run_id)

    def age_days(self, serial: str) -> float:
        """Days since the unit was first registered, on the runner's clock (0 for a new unit)."""
        with self.sessions.begin() as s:
            unit = get_unit_by_serial(s, serial)
            first = unit.created_at if unit is not None else None
        if first is None:
            return 0.0
        return max(0.0, (self.clock() - first).total_seconds() / 86400.0)

    def start(
        self, unit_serial: str, procedure: str, *, dwell_s: float | None = None, kind: RunKind = "calibration"
    ) -> LiveRun:
        """Queue a run and start its worker.

        :raises ValueError: unknown procedure or one the table limits refuse.
        :raises BenchBusy: another run holds the bench.
        """
        dwell_s = dwell_s if dwell_s is not None else self.settings.run_dwell_s
        proc = build_procedure(procedure, dwell_s=dwell_s)
        pv = preview(proc, SequencerConfig(temp_band_c=self.settings.temp_band_c).limits)
        if not pv.ok:
            raise ValueError(f"{procedure}: " + "; ".join(pv.problems))
        age = self.age_days(unit_serial)
        with self._lock:
            if self._current is not None:
                raise BenchBusy(self._current.id)
            live = LiveRun(
                new_run_id(unit_serial, self.clock()), unit_serial, procedure, kind, RunControl(), age
            )
            live.extra["dwell_s"] = dwell_s
            self._current = live
            self._thread = threading.Thread(
                target=self._work, args=(live,), name=f"bench-run-{live.id}", daemon=True
            )
        self.hub.publish(live.id, "state", {"state": "queued", "reason": "accepted"})
        self._thread.start()
        return live

    def abort(self, run_id: str, reason: str = "operator abort over REST") -> bool:
        """Ask the run to abort (table to its safe state, recording kept); False if not live."""
        live = self._current
        if live is None or live.id != run_id:
            return False
        live.control.abort(reason)
        return True

    def _work(self, live: LiveRun) -> None:
        record: RunRecord | None = None
        try:
            record = start_run(
                self.settings,
                live.procedure,
                live.unit_serial,
                sim=self.settings.sim,
                seed=self.settings.sim_seed,
                dwell_s=live.extra.get("dwell_s"),
                observers=[HubObserver(live, self.hub)],
                control=live.control,
                run_id=live.id,
                truth=simulated_unit(live.unit_serial, live.age_days) if self.settings.sim else None,
            )
            live.record = record
            live.error = record.error
            if self.finisher is not None:
                self.finisher(live, record)
        except Exception as exc:  # the worker must report, not die silently
            log.exception("run %s failed in the service", live.id)
            live.error = f"{type(exc).__name__}: {exc}"
        finally:
            live.state = _final_state(record)
            live.progress = 1.0 if live.state == "completed" else live.progress
            self.hub.publish(
                live.id,
                TERMINAL_EVENT,
                {"state": live.state, "outcome": record.outcome.value if record and record.outcome else None,
                 "error": live.error, **{k: v for k, v in live.extra.items() if k != "dwell_s"}},
            )
            with self._lock:
                self._recent[live.id] = live
                if len(self._recent) > 50:
                    self._recent.pop(next(iter(self._recent)))
                self._current = None
            live.done.set()

    def wait_idle(self, timeout_s: float) -> bool:
        """Wait until no run holds the bench; False on timeout."""
        live = self._current
        return True if live is None else live.done.wait(timeout_s)

    def shutdown(self, timeout_s: float = 30.0) -> None:
        """Abort the current run (if any) and wait for its worker."""
        live = self._current
        if live is not None:
            live.control.abort("service shutting down")
            live.done.wait(timeout_s)


def _final_state(record: RunRecord | None) -> str:
    if record is None or record.outcome is None:
        return "error"
    return _FINAL_STATE[record.outcome.value]


_FINAL_STATE = {"PASS": "completed", "FAIL": "failed", "ERROR": "error", "ABORTED": "aborted"}
