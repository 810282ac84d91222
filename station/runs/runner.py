"""The bench's runner: one worker thread at a time owns the bench and its sequencer.

:meth:`BenchRunner.start` validates the request, allocates the run id, and starts a worker
thread that calls :func:`station.execution.session.start_run` with a :class:`HubObserver` (progress
to the event streams) and then the finisher (fit, diagnosis, certificate or drift
comparison, in the database). :meth:`BenchRunner.resume` claims an ``interrupted`` run and
continues it from its next window in the same way (:mod:`station.runs.resume`);
:meth:`~BenchRunner.pause` and :meth:`~BenchRunner.continue_run` hold and release the live
run. A second start while a run holds the bench raises :class:`BenchBusy` (HTTP 409).
:meth:`~BenchRunner.shutdown` leaves the live run ``interrupted`` (table safe, recording
closed), not aborted, so it is resumed after a restart. How the worker's run ends in the
database, whatever ended it, is :mod:`station.runs.run_end`.

The simulated unit behind a serial is :func:`drivers.factory.simulated_unit` (seed CRC-32 of the
serial, aged ``age_days``), its age counted from the unit's first registration on the runner's
clock, so a sensor ages from day to day and tests can move the clock; a resumed run keeps the age
it started with.
"""

from __future__ import annotations

import datetime as dt
import logging
import socket
import threading
import time
from collections.abc import Callable

from sqlalchemy.orm import Session, sessionmaker

from bench.procedures import admit_procedure
from bench.records import RunRecord, new_run_id, utc_now
from bench.run_observer import RunObserver
from bench.run_state import Outcome, RunState
from bench.sequencer.control import RunControl
from db.repo.queue import enter_finishing
from db.repo.recovery import mark_interrupted_runs
from db.repo.units import get_unit_by_serial
from drivers.factory import simulated_unit
from station.execution.devices import table_limits
from station.execution.fault_retry import FAULT_PREFIX, ResumeFailed, RetryPolicy, interrupted_by_fault
from station.execution.session import start_run
from station.runs import resume as service_resume
from station.runs import run_end
from station.runs.analysis_eta import AnalysisPace, analysis_entry, analysis_pace
from station.runs.hub import TERMINAL_EVENT, ProgressHub
from station.runs.live import DbLiveObserver, HubObserver, LiveRun, RunKind, ServiceParamsObserver
from station.runs.resume import SHUTDOWN_REASON, NotResumable
from station.settings import Settings

__all__ = ["BenchBusy", "BenchRunner", "LiveRun", "NotResumable", "RunKind"]

log = logging.getLogger(__name__)

Finisher = Callable[[LiveRun, RunRecord], None]


class BenchBusy(Exception):
    """The bench is running another run (HTTP 409)."""

    def __init__(self, run_id: str) -> None:
        super().__init__(f"the bench is busy with run {run_id}; abort it or wait until it finishes")
        self.run_id = run_id


class BenchRunner:
    """Owns the bench: at most one run at a time, each in its own worker thread.

    :param settings: service settings (simulation, dwell, bench name).
    :param sessions: database session factory.
    :param hub: where progress events go.
    :param finisher: called in the worker after the run ended (stores results); its
        exceptions are logged and reported on the stream, the run's state stays as stored.
    :param clock: wall clock (UTC), replaceable in tests to age simulated units.
    :param store_live: also store each run's latest progress in the database
        (:class:`~station.runs.live.DbLiveObserver`), for API processes that do not hold the bench.
    """

    def __init__(
        self,
        settings: Settings,
        sessions: sessionmaker[Session],
        hub: ProgressHub,
        finisher: Finisher | None = None,
        clock: Callable[[], dt.datetime] = utc_now,
        store_live: bool = False,
    ) -> None:
        self.settings, self.sessions, self.hub = settings, sessions, hub
        self.store_live = store_live
        self.finisher = finisher
        self.clock = clock
        self._lock = threading.Lock()
        self._current: LiveRun | None = None
        self._thread: threading.Thread | None = None
        self._recent: dict[str, LiveRun] = {}
        self.retry = RetryPolicy()
        """When and how often a run a device fault interrupted is resumed automatically."""

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

    def _claim_bench(self, live: LiveRun, target: Callable[[LiveRun], None]) -> None:
        """Make ``live`` the run holding the bench and start its worker (caller holds the lock)."""
        if self._current is not None:
            raise BenchBusy(self._current.id)
        self._current = live
        self._thread = threading.Thread(target=target, args=(live,), name=f"bench-run-{live.id}", daemon=True)

    def start(
        self,
        unit_serial: str,
        procedure: str,
        *,
        dwell_s: float | None = None,
        kind: RunKind = "calibration",
        run_id: str | None = None,
        parameters: dict[str, float] | None = None,
    ) -> LiveRun:
        """Start a run's worker.

        :param run_id: the id of a run this process has claimed from the queue
            (:mod:`db.repo.queue`); default: a new id.
        :param parameters: the procedure's own parameters (``build_procedure`` keywords).
        :raises ProcedureRefused: what refuses the procedure (a ``ValueError``:
            :func:`~bench.procedures.check_procedure`).
        :raises BenchBusy: another run holds the bench.
        """
        dwell_s = dwell_s if dwell_s is not None else self.settings.run_dwell_s
        limits = table_limits(self.settings)
        admit_procedure(procedure, limits, dwell_s=dwell_s, parameters=parameters)
        age = self.age_days(unit_serial)
        with self._lock:
            live = LiveRun(
                run_id or new_run_id(unit_serial, self.clock()),
                unit_serial,
                procedure,
                kind,
                RunControl(),
                age,
            )
            live.extra["dwell_s"] = dwell_s
            live.extra["procedure_kw"] = dict(parameters or {})
            self._claim_bench(live, self._work)
        self.hub.publish(live.id, "state", {"state": RunState.QUEUED.value, "reason": "accepted"})
        assert self._thread is not None
        self._thread.start()
        return live

    def resume(self, run_id: str) -> LiveRun:
        """Continue an ``interrupted`` run from the window after its last complete one.

        The run is claimed in the database before this returns, so a refusal is immediate.

        :raises LookupError: no such run. :raises NotResumable: its state or recording forbids it.
        :raises BenchBusy: another run holds the bench.
        """
        with self.sessions.begin() as s:
            mark_interrupted_runs(s, socket.gethostname())  # a run whose owner has died since
            service_resume.check_resumable(s, run_id, self.settings)
        with self._lock:
            if self._current is not None:
                raise BenchBusy(self._current.id)
            with self.sessions.begin() as s:
                claimed = service_resume.claim(s, run_id)
            live = self._hold_claimed(claimed)
        return self._launch_resumed(live)

    def resume_claimed(self, claimed: service_resume.Claimed) -> LiveRun:
        """Continue a run this process has already claimed (from the queue) from its next window.

        :raises BenchBusy: another run holds the bench.
        """
        with self._lock:
            live = self._hold_claimed(claimed)
        return self._launch_resumed(live)

    def _hold_claimed(self, claimed: service_resume.Claimed) -> LiveRun:
        """The live run of a claimed resume, holding the bench (call with ``_lock`` held)."""
        age = claimed.sim_age_days
        live = LiveRun(
            claimed.run_id,
            claimed.unit_serial,
            claimed.procedure,
            claimed.kind,
            RunControl(),
            age if age is not None else 0.0,
            resumed=True,
        )
        live.extra["claimed"] = claimed
        live.extra["resumed_from_window"] = claimed.point.next_window_index
        self._claim_bench(live, self._work)
        return live

    def _launch_resumed(self, live: LiveRun) -> LiveRun:
        self.hub.publish(live.id, "state", {"state": RunState.QUEUED.value, "reason": "resume accepted"})
        assert self._thread is not None
        self._thread.start()
        return live

    def _held(self, run_id: str) -> LiveRun | None:
        live = self._current
        return live if live is not None and live.id == run_id else None

    def abort(self, run_id: str, reason: str = "operator abort over REST") -> bool:
        """Ask the run to abort (table to its safe state, recording kept); False if not live."""
        live = self._held(run_id)
        if live is None:
            return False
        return live.control.abort(reason)

    def pause(self, run_id: str) -> bool:
        """Hold the live run: the window in progress is dropped and recorded again on continue;
        False if the run does not hold the bench."""
        live = self._held(run_id)
        if live is None:
            return False
        return live.control.pause()

    def continue_run(self, run_id: str) -> bool:
        """Release a pause; for a run suspended by an interlock or the temperature band, the
        operator's go-ahead (the table is prepared again). False if the run does not hold the bench."""
        live = self._held(run_id)
        if live is None:
            return False
        live.control.resume()
        return True

    def _observers(self, live: LiveRun) -> list[RunObserver]:
        observers: list[RunObserver] = [
            ServiceParamsObserver(live, self.sessions, self.settings.sim),
            HubObserver(live, self.hub),
        ]
        if self.store_live:
            observers.append(DbLiveObserver(self.sessions, live=live))
        return observers

    def _acquire(self, live: LiveRun) -> RunRecord:
        """Execute (or continue) the run on the bench, to its verdict."""
        if live.resumed:
            claimed = live.extra["claimed"]
            truth = None
            if self.settings.sim and claimed.sim_age_days is not None:
                truth = simulated_unit(live.unit_serial, claimed.sim_age_days)
            return service_resume.execute(
                self.settings,
                self.sessions,
                claimed,
                truth=truth,
                observers=self._observers(live),
                control=live.control,
                defer_final_state=True,
            )
        return start_run(
            self.settings,
            live.procedure,
            live.unit_serial,
            sim=self.settings.sim,
            seed=self.settings.sim_seed,
            dwell_s=live.extra.get("dwell_s"),
            observers=self._observers(live),
            control=live.control,
            run_id=live.id,
            procedure_kw=live.extra.get("procedure_kw") or None,
            truth=simulated_unit(live.unit_serial, live.age_days) if self.settings.sim else None,
            defer_final_state=True,
        )

    def _analysis_pace(self, procedure: str) -> AnalysisPace | None:
        """This bench's analysis pace for ``procedure`` (``None``: none analysed yet, or the
        database did not answer: the run goes on without the estimate)."""
        try:
            with self.sessions.begin() as s:
                return analysis_pace(s, self.settings.bench_name, procedure)
        except Exception:
            log.exception("could not read the analysis history of %s", procedure)
            return None

    def _finishing_gate(self, run_id: str) -> str | None:
        """The stored abort of ``run_id``, else the run marked finishing in the database in the
        same transaction (:func:`db.repo.queue.enter_finishing`): a request either took effect
        or is refused from here on."""
        with self.sessions.begin() as s:
            return enter_finishing(s, run_id)

    def _work(self, live: LiveRun) -> None:
        record: RunRecord | None = None
        interrupted = False
        live.control.finishing_gate = lambda: self._finishing_gate(live.id)
        live.analysis = self._analysis_pace(live.procedure)
        try:
            record = self._acquire(live)
            live.record = record
            live.error = record.error
            if interrupted_by_fault(record):  # table safe, recording closed: resumed automatically
                interrupted = True
                run_end.schedule_resume(
                    self.sessions, live, record.error or FAULT_PREFIX, len(record.windows), self.retry
                )
            elif live.shutdown and record.outcome is Outcome.ABORTED:
                with self.sessions.begin() as s:
                    interrupted = service_resume.interrupt_shutdown_abort(s, live.id)
            elif self.finisher is not None:
                self.finisher(live, record)
        except ResumeFailed as exc:  # the devices did not open: put back interrupted, tried again
            live.error, interrupted = str(exc), True
            claimed = live.extra.get("claimed")
            windows = claimed.point.next_window_index if claimed else 0
            run_end.schedule_resume(self.sessions, live, str(exc), windows, self.retry)
        except Exception as exc:  # the worker must report, not die silently
            log.exception("run %s failed in the service", live.id)
            live.error = f"{type(exc).__name__}: {exc}"
            if live.resumed and record is None:  # claimed but not continued: resumable again
                interrupted = run_end.release_claim(self.sessions, live)
                if interrupted:
                    run_end.after_failed_resume(self.sessions, live, exc, self.retry)
            elif record is None:  # a claimed run must not stay live without an owner at work
                run_end.store_error(self.sessions, live)
        finally:
            if record is not None and not interrupted:
                run_end.store_final_state(self.sessions, live, record)
            live.state = RunState.INTERRUPTED if interrupted else run_end.final_state(record)
            live.progress = 1.0 if live.state is RunState.COMPLETED else live.progress
            if live.state is RunState.COMPLETED and live.analysing_since is not None:
                wall_s = time.monotonic() - live.analysing_since
                live.extra.update(analysis_entry(wall_s))
            finished = run_end.terminal_event(live, record)
            self.hub.publish(live.id, TERMINAL_EVENT, finished)
            run_end.store_final_event(self.sessions, live, finished)
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

    def shutdown(self, timeout_s: float = 60.0) -> str | None:
        """Stop the live run for a service shutdown and wait for its worker: the table goes to
        its safe state, the recording is closed with its durable chunks, and the run is stored
        ``interrupted`` (resumable after the restart), not aborted. Returns its id, if any."""
        live = self._current
        if live is None:
            return None
        live.shutdown = True
        live.control.abort(SHUTDOWN_REASON)
        if not live.done.wait(timeout_s):
            log.error(
                "run %s did not stop within %g s of the shutdown; the next start marks it interrupted",
                live.id,
                timeout_s,
            )
        return live.id
