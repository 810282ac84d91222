"""The bench agent: the one process per table that owns the table, the DAQ, the sequencer and
the recording (``calbench agent``).

API processes never touch hardware: they queue runs and control requests in the database
(:mod:`db.repo.queue`, :class:`station.runs.queue.RunQueue`). The agent of bench
``CALBENCH_BENCH_NAME`` polls the database every ``poll_s``: while its bench is free it
claims the oldest queued run of the bench (row locking, so two agents or a restart never
claim one run twice) and executes it on its :class:`~station.runs.runner.BenchRunner`, fresh or
resumed from the window after its last complete one; while a run holds the bench it applies
the abort, pause and continue requests stored for it. Progress, windows, chunks, the final
state, the fit, the diagnosis and the certificate go to the database as they happen, so any
number of API processes can show them, and an API process can die or restart while the run
records. The agent itself can restart: a run it held is then ``interrupted`` and resumes from
its last complete window when an operator asks (``POST /api/runs/{id}/resume``). A run a
device fault interrupted (a stalled or reset table, a lost link, a DAQ timeout, a full disk)
is resumed by the agent itself when its next try is due (:mod:`station.execution.fault_retry`); the
bench takes no other run meanwhile.

On SIGTERM/SIGINT the agent stops the run it holds with the table safe and the recording
closed, stored ``interrupted`` (resumable), as the service did before it had an agent.

Every :data:`PRESENCE_S` the agent tells the database it is alive, with the procedures its
table can run and its bench file's identity (:mod:`db.repo.benches`), so the API can list the
benches with their state and send a run to a free bench that can run it; on a clean stop it
marks its bench offline.
"""

from __future__ import annotations

import datetime as dt
import logging
import math
import os
import socket
import threading
import time
from collections.abc import Callable

import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from bench.bench_config import BenchConfig
from bench.procedures import PROCEDURES, ProcedureRefused, Refusal, RefusalKind, check_procedure
from bench.records import RunRecord, utc_now
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import AGENT, Run, RunState
from db.models.run_params import PARAMETERS
from db.observer import finish_record
from db.process import process_start_ticks
from db.repo.benches import agent_alive, agent_gone
from db.repo.queue import ClaimedRun, claim_next_run, pending_control, queue_resume
from db.repo.recovery import mark_interrupted_runs
from db.repo.runs import finish_run, set_service_run
from db.repo.units import get_or_create_bench, get_unit_by_serial
from station.certificates.issue import finish_calibration, prepare_run, unit_nominal
from station.disk_full import DiskFullWatch
from station.drift import record_drift_check
from station.execution import fault_retry
from station.execution.devices import bench_config_for
from station.runs import resume as service_resume
from station.runs.hub import ProgressHub
from station.runs.live import LiveRun, store_phase
from station.runs.runner import BenchBusy, BenchRunner
from station.settings import Settings

log = logging.getLogger(__name__)

POLL_S = 0.25
"""How often the agent looks for queued runs and control requests (s)."""
PRESENCE_S = 5.0
"""How often the agent tells the database it is alive (s); well under ``AGENT_STALE_S``."""


def runnable_procedures(settings: Settings, config: BenchConfig) -> list[str]:
    """The registered procedures the bench of ``config`` can run: as many table axes as the
    procedure needs and a preview the sequencer's table limits accept.

    :raises ProcedureRefused: a procedure refuses the settings' ``run_dwell_s``."""
    limits = config.table_limits()
    out = []
    for name in sorted(PROCEDURES):
        checked = check_procedure(name, limits, dwell_s=settings.run_dwell_s)
        if isinstance(checked, Refusal):
            if checked.kind is not RefusalKind.TABLE_LIMITS:  # the settings' dwell: a bad setting
                raise ProcedureRefused(checked)
            continue
        if checked.procedure.n_axes == len(config.axes):
            out.append(name)
    return out


def make_finisher(
    settings: Settings, sessions: sessionmaker[Session], read_sessions: sessionmaker[Session]
) -> Callable[[LiveRun, RunRecord], None]:
    """What the runner's worker does after a run: results, certificate or drift comparison.

    Everything slow (the diagnosis, the certificate's budget: for a moving table minutes of
    refits) is done on the run's analysis before the write transaction opens, so the API's
    writes never wait for it."""

    def finish(live: LiveRun, record: RunRecord) -> None:
        analysis = None
        if live.kind == "calibration":
            with read_sessions.begin() as s:
                nominal = unit_nominal(get_unit_by_serial(s, live.unit_serial))
                run = s.get(Run, record.run_id)
                params = dict(run.params) if run is not None else {}
            analysis = prepare_run(record, nominal, settings, params)
        live.phase = "certificate"
        store_phase(sessions, record.run_id, "certificate")
        with sessions.begin() as s:
            set_service_run(s, record.run_id, live.kind)
            # the final state commits in one transaction with the certificate (or drift check):
            # a run that reads completed has them
            finish_record(s, record)
            if live.kind == "calibration":
                cert = finish_calibration(s, settings, record, analysis)
                live.extra["certificate_number"] = cert.number if cert is not None else None
            else:
                check = record_drift_check(s, settings, live.unit_serial, record)
                live.extra["drift_flagged"] = check.flagged
                live.extra["drift_check_id"] = check.id

    return finish


class BenchAgent:
    """Claims the queued runs of one bench and executes them, one at a time.

    :param settings: the bench (``bench_name``, devices or ``sim``) and its database.
    :param clock: wall clock of the runner (ages simulated units; tests move it).
    :param poll_s: interval of the queue and control polls (s).
    :param lease_token: the fencing token of the bench's lease this process holds
        (:class:`station.execution.bench_lock.BenchLock`): runs are claimed only while it is the
        bench's; ``None``: no lease (an agent embedded in a test's app).
    """

    def __init__(
        self,
        settings: Settings,
        *,
        clock: Callable[[], dt.datetime] = utc_now,
        poll_s: float = POLL_S,
        lease_token: int | None = None,
    ) -> None:
        self.settings, self.poll_s, self.lease_token = settings, poll_s, lease_token
        self.engine = open_database(settings.effective_database_url)
        self.sessions = make_session_factory(self.engine)
        self.read_sessions = make_session_factory(self.engine, read_only=True)
        with self.sessions.begin() as s:
            self.bench_id = get_or_create_bench(s, settings.bench_name).id
        finisher = make_finisher(settings, self.sessions, self.read_sessions)
        self.runner = BenchRunner(
            settings, self.sessions, ProgressHub(), finisher, clock=clock, store_live=True
        )
        self.pid, self.host = os.getpid(), socket.gethostname()
        self.start_ticks = process_start_ticks(self.pid)
        config = bench_config_for(settings, settings.sim)
        self.procedures = runnable_procedures(settings, config)
        self.bench_file = config.identity()
        self._announced = -math.inf
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._applied: tuple[str, int, bool] | None = None  # (run id, control seq, abort sent)
        self.disk_full = DiskFullWatch(log, f"bench agent {settings.bench_name}")

    def recover(self) -> list[str]:
        """Mark runs left live by a dead owner (a previous agent) ``interrupted``; their ids."""
        with self.sessions.begin() as s:
            marked = mark_interrupted_runs(s, self.host) + service_resume.recover_shutdown_aborts(s)
        if marked:
            log.warning("runs left live by a dead process, now interrupted: %s", ", ".join(marked))
        return marked

    def announce(self) -> None:
        """Tell the database this agent is alive, what its bench can run and its bench file."""
        with self.sessions.begin() as s:
            agent_alive(
                s,
                self.bench_id,
                pid=self.pid,
                host=self.host,
                procedures=self.procedures,
                bench_file=self.bench_file,
                start_ticks=self.start_ticks,
            )
        self._announced = time.monotonic()

    def tick(self) -> str | None:
        """One poll: claim and start the next queued run while the bench is free, or apply the
        control requests of the run holding it (and say it is alive every :data:`PRESENCE_S`).
        Returns the id of a run started now."""
        if time.monotonic() - self._announced >= PRESENCE_S:
            self.announce()
        cur = self.runner.current
        if cur is not None:
            self._apply_control(cur)
            return None
        self.end_orphans()
        with self.sessions.begin() as s:  # a run a device fault interrupted goes first, when due
            due, waiting = fault_retry.due_resume(s, self.bench_id)
            if due is not None:
                try:
                    queue_resume(s, due, actor=AGENT)
                except ValueError as exc:  # its recording no longer cuts at a window: not resumable
                    fault_retry.give_up(s, due, str(exc))
                    due = None
        if waiting and due is None:
            return None  # the bench is kept for it
        with self.sessions.begin() as s:
            claimed = claim_next_run(
                s, self.bench_id, owner_pid=self.pid, owner_host=self.host, lease_token=self.lease_token
            )
        if claimed is None:
            return None
        self._start(claimed)
        return claimed.run_id

    def end_orphans(self) -> list[str]:
        """End as ERROR the runs this process owns in a live state although its runner is idle
        (their end could not be stored when they ended: the database refused a write), so no
        run stays ``running`` for ever; their ids. Call only while the runner holds no run."""
        with self.sessions.begin() as s:
            ids = list(
                s.scalars(
                    sa.select(Run.id).where(
                        Run.owner_pid == self.pid,
                        Run.owner_host == self.host,
                        Run.state.in_([RunState.RUNNING, RunState.PAUSED, RunState.SUSPENDED]),
                    )
                )
            )
            for run_id in ids:
                finish_run(
                    s,
                    run_id,
                    RunState.ERROR,
                    outcome="ERROR",
                    error="the run ended but its end could not be stored (a database write failed); "
                    "its recording holds the chunks the database counts",
                )
        if ids:
            log.error("runs whose end could not be stored, now error: %s", ", ".join(ids))
        return ids

    def _start(self, claimed: ClaimedRun) -> None:
        self._applied = (claimed.run_id, 0, False)
        try:
            if claimed.point is not None:
                self.runner.resume_claimed(service_resume.from_queue(claimed))
                return
            self.runner.start(
                claimed.unit_serial,
                claimed.procedure,
                dwell_s=claimed.requested_dwell_s,
                kind="drift_check" if claimed.kind == "drift_check" else "calibration",
                run_id=claimed.run_id,
                parameters=claimed.params.get(PARAMETERS),
            )
        except (ValueError, BenchBusy) as exc:  # never leave a claimed run live without a worker
            log.error("run %s could not start: %s", claimed.run_id, exc)
            with self.sessions.begin() as s:
                finish_run(
                    s, claimed.run_id, RunState.ERROR, outcome="ERROR", error=f"could not start: {exc}"
                )

    def _apply_control(self, live: LiveRun) -> None:
        with self.read_sessions.begin() as s:
            pending = pending_control(s, live.id)
        run_id, seq, aborted = (
            self._applied if self._applied and self._applied[0] == live.id else (live.id, 0, False)
        )
        if pending.abort and not aborted:
            self.runner.abort(live.id, pending.abort)
            aborted = True
        if pending.seq > seq:
            if pending.action == "pause":
                self.runner.pause(live.id)
            elif pending.action == "continue":
                self.runner.continue_run(live.id)
            seq = pending.seq
        self._applied = (run_id, seq, aborted)

    def run_forever(self) -> None:
        """Poll until :meth:`stop`; a failing poll is logged and the next one tries again. A
        full disk is logged once (then once a minute, and when it clears), not at every poll,
        and polled less often while it lasts (:class:`~station.disk_full.DiskFullWatch`)."""
        while not self._stop.is_set():
            try:
                self.tick()
            except Exception as exc:
                if not self.disk_full.failed(exc):
                    log.exception("bench agent %s: poll failed", self.settings.bench_name)
            else:
                self.disk_full.succeeded()
            self._stop.wait(self.disk_full.wait_s(self.poll_s))

    def start(self) -> None:
        """Recover, then poll in a thread of this process."""
        self.recover()
        self._thread = threading.Thread(target=self.run_forever, name="bench-agent", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 60.0) -> str | None:
        """Stop polling and leave the run holding the bench ``interrupted`` (table safe,
        recording closed, resumable); its id, if any."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10.0)
        stopped = self.runner.shutdown(timeout_s)
        try:
            with self.sessions.begin() as s:
                agent_gone(s, self.bench_id, pid=self.pid, host=self.host)
        except Exception:  # the database is gone too: the bench shows offline once the record is stale
            log.exception("bench agent %s: could not mark the bench offline", self.settings.bench_name)
        if stopped is not None:
            log.warning("run %s interrupted by the agent's shutdown; resume it after the restart", stopped)
        return stopped

    def close(self) -> None:
        """Release the database."""
        self.engine.dispose()
