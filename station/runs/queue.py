"""The API's side of the bench: runs and control requests go to the database, never to hardware.

:class:`RunQueue` has the runner's interface (``start``, ``resume``, ``abort``, ``pause``,
``continue_run``, ``current``, ``wait_idle``), so the routes and the drift scheduler use it
as they used the in-process runner, but every call is a database write or read
(:mod:`db.repo.queue`): a start queues a run for the bench the client names, or for a free
bench whose agent can run the procedure (:func:`db.repo.benches.choose_bench`; this API's bench,
``CALBENCH_BENCH_NAME``, when no agent reports), and answers at once, also while the bench is
busy; the bench's agent (:mod:`station.agent.bench_agent`) claims it when the bench is free. Any
number of API processes can serve the benches, and any can restart while a run records: none
keeps state of its own.
"""

from __future__ import annotations

import datetime as dt
import socket
import time
from collections.abc import Callable

import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from bench.procedures import admit_procedure
from bench.records import new_run_id, utc_now
from bench.sequencer.control import RunControl
from db.models import ACTIVE_STATES, FINAL_STATES, SYSTEM, Run, Unit
from db.models.run_params import BENCH, PARAMETERS
from db.process import process_alive
from db.repo.benches import bench_status, choose_bench, find_bench
from db.repo.queue import (
    ControlAction,
    bench_id_of,
    holding_run,
    queue_resume,
    queue_run,
    queued_runs,
    request_control,
)
from db.repo.recovery import DEFAULT_STALE_AFTER_S, mark_interrupted_runs
from db.repo.units import get_or_create_bench, get_or_create_unit, get_unit_by_serial
from station.execution.devices import table_limits
from station.runs import resume as service_resume
from station.runs.live import LiveRun, RunKind
from station.runs.resume import NotResumable
from station.settings import Settings

__all__ = ["NotResumable", "RunQueue", "UnknownBench"]


class UnknownBench(ValueError):
    """A run asked for a bench the database does not know, or one that cannot run its procedure
    (HTTP 422, the bench named)."""


class RunQueue:
    """Queue and control the runs of one bench through the database.

    :param settings: this API's bench (``bench_name``) and default dwell.
    :param sessions: writing sessions; :param read_sessions: read-only sessions.
    :param clock: wall clock (run ids, unit ages).
    """

    def __init__(
        self,
        settings: Settings,
        sessions: sessionmaker[Session],
        read_sessions: sessionmaker[Session],
        clock: Callable[[], dt.datetime] = utc_now,
    ) -> None:
        self.settings, self.sessions, self.read_sessions, self.clock = (
            settings,
            sessions,
            read_sessions,
            clock,
        )

    def age_days(self, serial: str) -> float:
        """Days since the unit was first registered, on this clock (0 for a new unit)."""
        with self.read_sessions.begin() as s:
            unit = get_unit_by_serial(s, serial)
            first = unit.created_at if unit is not None else None
        return 0.0 if first is None else max(0.0, (self.clock() - first).total_seconds() / 86400.0)

    @property
    def current(self) -> LiveRun | None:
        """The run holding the bench (running, paused, suspended), or a run whose agent is still
        storing its results and certificate; ``None`` when the bench is free."""
        with self.read_sessions.begin() as s:
            bench_id = bench_id_of(s, self.settings.bench_name)
            if bench_id is None:
                return None
            run = holding_run(s, bench_id) or self._storing(s, bench_id)
            if run is None:
                return None
            serial = s.scalar(sa.select(Unit.serial).where(Unit.id == run.unit_id)) or "?"
            return _live_of(run, serial)

    def _storing(self, s: Session, bench_id: int) -> Run | None:
        cutoff = utc_now() - dt.timedelta(seconds=DEFAULT_STALE_AFTER_S)
        rows = s.scalars(
            sa.select(Run)
            .where(Run.bench_id == bench_id, Run.state.in_(list(FINAL_STATES)), Run.finished_at > cutoff)
            .order_by(Run.finished_at.desc())
            .limit(3)
        )
        for run in rows:
            service = run.kind is not None
            # a run aborted while queued was never owned: nothing is storing it
            owner_alive = run.owner_host is not None and (
                run.owner_host != socket.gethostname()
                or (run.owner_pid is not None and process_alive(run.owner_pid))
            )
            if service and run.final_event is None and owner_alive:
                return run
        return None

    def live(self, run_id: str) -> LiveRun | None:
        """Nothing: this process holds no run; stored rows say everything."""
        return None

    def start(
        self,
        unit_serial: str,
        procedure: str,
        *,
        dwell_s: float | None = None,
        kind: RunKind = "calibration",
        bench: str | None = None,
        drift_night: str | None = None,
        actor: str = SYSTEM,
        parameters: dict[str, float] | None = None,
    ) -> LiveRun:
        """Queue a run on ``bench`` (also while it is busy); its agent starts it when free.
        A drift check of a unit that has one queued or running already is that one, and so is a
        drift check queued for the same ``drift_night`` in whatever state (several API processes
        each run the nightly scheduler: a unit is checked once a night).

        :param bench: a bench's name or its bench file's name; ``None``: a free bench that can run
            the procedure (:meth:`bench_for`), a drift check this API's bench.
        :param drift_night: the scheduled time of the night a drift check is for (ISO 8601, the
            same in every API process); stored with the run (``Run.drift_night``).
        :param actor: who asks (the operator's name; the drift scheduler: ``system``), stored in
            the run's audit trail.
        :param parameters: the procedure's own parameters (``build_procedure`` keywords), stored in
            the run's ``params`` (``parameters``) for the agent.
        :raises UnknownBench: no such bench, or it cannot run the procedure (named).
        :raises ProcedureRefused: what refuses the procedure (a ``ValueError``:
            :func:`~bench.procedures.check_procedure`).
        """
        dwell_s = dwell_s if dwell_s is not None else self.settings.run_dwell_s
        limits = table_limits(self.settings)
        admit_procedure(procedure, limits, dwell_s=dwell_s, parameters=parameters)
        now = self.clock()
        run_id = new_run_id(unit_serial, now)
        with self.sessions.begin() as s:
            name = self.bench_for(s, procedure, bench, kind)
            params: dict[str, object] = {BENCH: name}
            if parameters:
                params[PARAMETERS] = dict(parameters)
            bench_row = get_or_create_bench(s, name)
            unit = get_or_create_unit(s, unit_serial, bench_id=bench_row.id)
            if kind == "drift_check":  # every API process has a scheduler: one check per unit at a time
                # the unit's row lock orders two processes queueing its check (PostgreSQL; SQLite
                # writers are alone anyway)
                s.execute(sa.select(Unit.id).where(Unit.id == unit.id).with_for_update())
                for run in s.scalars(sa.select(Run).where(Run.unit_id == unit.id, Run.kind == "drift_check")):
                    same_night = drift_night is not None and run.drift_night == drift_night
                    if run.state in ACTIVE_STATES or same_night:
                        return _live_of(run, unit_serial)
            queue_run(
                s,
                run_id,
                unit.id,
                bench_row.id,
                procedure,
                params,
                kind=kind,
                requested_dwell_s=dwell_s,
                drift_night=drift_night if kind == "drift_check" else None,
                actor=actor,
            )
        created = LiveRun(run_id, unit_serial, procedure, kind, RunControl(), 0.0)
        created.extra["bench"] = name
        return created

    def bench_for(self, s: Session, procedure: str, bench: str | None, kind: RunKind) -> str:
        """The name of the bench a run goes to (see :meth:`start`).

        :raises UnknownBench: ``bench`` is not known or its agent says it cannot run ``procedure``.
        """
        own = self.settings.bench_name
        if bench is None and kind == "drift_check":
            return own
        statuses = bench_status(s)
        if bench is None:
            return choose_bench(statuses, procedure, own) or own
        if bench == own and all(st.name != own for st in statuses):
            return own  # this service's bench before its agent first reported
        try:
            status = find_bench(statuses, bench)
        except LookupError as exc:
            raise UnknownBench(str(exc)) from None
        if not status.can_run(procedure):
            raise UnknownBench(
                f"bench {status.name!r} cannot run {procedure}; it runs {', '.join(status.procedures)}"
            )
        return status.name

    def resume(self, run_id: str, actor: str = SYSTEM) -> LiveRun:
        """Queue an ``interrupted`` run to continue from the window after its last complete one
        (``actor`` asks: stored in its audit trail).

        :raises LookupError: no such run. :raises NotResumable: its state or recording forbids it.
        :raises ResumeRefused: its procedure is unknown here, no longer rebuilds from its stored
            parameters, or what remains breaks the table's limits (the run is left as it was).
        """
        with self.sessions.begin() as s:
            mark_interrupted_runs(s, socket.gethostname())  # a run whose owner has died since
            run = service_resume.check_resumable(s, run_id, self.settings)
            try:
                point = queue_resume(s, run_id, actor=actor)
            except ValueError as exc:
                raise NotResumable(str(exc)) from None
            if point is None:
                raise NotResumable(f"run {run_id} is no longer interrupted")
            serial = s.scalar(sa.select(Unit.serial).where(Unit.id == run.unit_id)) or "?"
            live = _live_of(run, serial)
        live.extra["resumed_from_window"] = point.next_window_index
        return live

    def _request(self, run_id: str, action: ControlAction, reason: str = "", actor: str = SYSTEM) -> bool:
        try:
            with self.sessions.begin() as s:
                return request_control(s, run_id, action, reason, actor=actor) is not None
        except LookupError:
            return False

    def abort(self, run_id: str, reason: str = "operator abort over REST", actor: str = SYSTEM) -> bool:
        """Ask the bench's agent to abort the run (a queued one ends at once); False if not live.
        ``actor`` (who asks) goes into the run's audit trail, as for every request below."""
        return self._request(run_id, "abort", reason, actor)

    def pause(self, run_id: str, actor: str = SYSTEM) -> bool:
        """Ask the agent to hold the run; False if it is not live."""
        return self._request(run_id, "pause", actor=actor)

    def continue_run(self, run_id: str, actor: str = SYSTEM) -> bool:
        """Ask the agent to let a paused or suspended run go on; False if it is not live."""
        return self._request(run_id, "continue", actor=actor)

    def queued(self) -> list[str]:
        """Ids of the bench's queued runs, in the order the agent takes them."""
        with self.read_sessions.begin() as s:
            bench_id = bench_id_of(s, self.settings.bench_name)
            return [] if bench_id is None else [r.id for r in queued_runs(s, bench_id)]

    def wait_idle(self, timeout_s: float, poll_s: float = 0.2) -> bool:
        """Wait until the bench holds no run and none is queued; False on timeout."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.current is None and not self.queued():
                return True
            time.sleep(poll_s)
        return False

    def shutdown(self, timeout_s: float = 60.0) -> None:
        """Nothing to stop: the bench's agent owns the run."""
        return None


def _live_of(run: Run, serial: str) -> LiveRun:
    live = LiveRun(
        run.id,
        serial,
        run.procedure,
        "drift_check" if run.kind == "drift_check" else "calibration",
        RunControl(),
        0.0,
        state=run.state,
        progress=run.progress,
        error=run.error,
    )
    if run.created_at is not None:
        live.created_at = run.created_at
    return live
