"""The service: ``create_app(settings)`` wires database, runner, drift scheduler, auth and routes.

The lifespan opens (creates and migrates) the database, marks runs left live by a dead
process ``interrupted`` (and runs a previous shutdown stopped, see
:mod:`api.service_resume`), starts the drift scheduler's thread, and on shutdown stops the
scheduler and leaves the run holding the bench ``interrupted`` — table safe, recording
closed, resumable with ``POST /api/runs/{id}/resume`` after the restart. On SIGTERM/SIGINT
the open event streams end first, so the server does not wait for them before the run is
stopped. Nothing is read from the environment here:
the caller builds ``Settings`` (``calbench serve`` does, from ``CALBENCH_*``).

The dashboard (``api/static`` at ``/static`` and ``GET /`` from ``api.routes.dashboard``,
each when present) is mounted beside the JSON API.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import importlib
import importlib.util
import logging
import signal
import socket
import threading
from collections.abc import AsyncIterator, Callable, Iterator
from contextlib import asynccontextmanager, contextmanager
from pathlib import Path

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles
from sqlalchemy.orm import Session, sessionmaker

from api.analysis_worker import AnalysisPool
from api.auth import Authenticator, Role, parse_tokens
from api.certificates.issue import analyse_run, finish_calibration, unit_nominal
from api.deps import Services
from api.drift import DriftScheduler, record_drift_check
from api.progress_hub import ProgressHub
from api.routes import api_router
from api.runner import BenchRunner, LiveRun
from api.service_resume import recover_shutdown_aborts
from api.settings import Settings
from bench.records import RunRecord, utc_now
from db.engine import make_session_factory, open_database
from db.repo.recovery import mark_interrupted_runs
from db.repo.runs import merge_params
from db.repo.units import get_unit_by_serial

log = logging.getLogger(__name__)
STATIC_DIR = Path(__file__).resolve().parent / "static"
DESCRIPTION = """Accelerometer calibration bench service.

Roles: a **viewer** token reads, an **operator** token also starts and aborts runs, issues
certificates, uploads recordings and starts drift checks. Send `Authorization: Bearer TOKEN`.
Missing or unknown token: 401; a role too low: 403. One run at a time per bench: a second
start gets 409.
"""


def make_finisher(
    settings: Settings, sessions: sessionmaker[Session], read_sessions: sessionmaker[Session]
) -> Callable[[LiveRun, RunRecord], None]:
    """What the runner's worker does after a run: results, certificate or drift comparison.

    The recording is read and diagnosed before the write transaction opens."""

    def finish(live: LiveRun, record: RunRecord) -> None:
        analysis = None
        if live.kind == "calibration":
            with read_sessions.begin() as s:
                nominal = unit_nominal(get_unit_by_serial(s, live.unit_serial))
            analysis = analyse_run(record, nominal)
        with sessions.begin() as s:
            merge_params(s, record.run_id, {"service_kind": live.kind})
            if live.kind == "calibration":
                cert = finish_calibration(s, settings, record, analysis)
                live.extra["certificate_number"] = cert.number if cert is not None else None
            else:
                check = record_drift_check(s, settings, live.unit_serial, record)
                live.extra["drift_flagged"] = check.flagged
                live.extra["drift_check_id"] = check.id

    return finish


def build_services(settings: Settings, clock: Callable[[], dt.datetime] = utc_now) -> Services:
    """Open the database (migrating it) and build runner, scheduler and authenticator.

    :raises ValueError: a malformed ``CALBENCH_TOKENS`` entry or ``CALBENCH_DRIFT_TIME``.
    """
    env_tokens = parse_tokens(settings.tokens)
    engine = open_database(settings.effective_database_url)
    sessions = make_session_factory(engine)
    read_sessions = make_session_factory(engine, read_only=True)
    with sessions.begin() as s:
        marked = mark_interrupted_runs(s, socket.gethostname()) + recover_shutdown_aborts(s)
    if marked:
        log.warning("runs left live by a dead process, now interrupted: %s", ", ".join(marked))
    hub = ProgressHub()
    finisher = make_finisher(settings, sessions, read_sessions)
    runner = BenchRunner(settings, sessions, hub, finisher, clock=clock)
    drift = DriftScheduler(settings, sessions, runner, clock=clock)
    auth = Authenticator(env_tokens, sessions, read_sessions, public_read=settings.public_read)
    analysis = AnalysisPool(settings.upload_workers)
    return Services(settings, engine, sessions, read_sessions, hub, runner, drift, auth, analysis)


@contextmanager
def streams_end_on_signal(hub: ProgressHub) -> Iterator[None]:
    """While the server runs, SIGTERM and SIGINT first end every open event stream, then go to
    the server's own handler (which waits for open responses before the lifespan's shutdown
    stops the run). Outside the main thread (a test client) nothing is installed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    loop = asyncio.get_running_loop()
    previous: dict[signal.Signals, object] = {}

    def handler(signum: int, frame: object) -> None:
        loop.call_soon_threadsafe(hub.close_all, f"the service is stopping ({signal.Signals(signum).name})")
        prev = previous.get(signal.Signals(signum))
        if callable(prev):
            prev(signum, frame)

    for sig in (signal.SIGTERM, signal.SIGINT):
        previous[sig] = signal.getsignal(sig)
        signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, prev in previous.items():
            signal.signal(sig, prev)  # type: ignore[arg-type]


def create_app(
    settings: Settings,
    *,
    clock: Callable[[], dt.datetime] = utc_now,
    start_scheduler: bool = True,
    extra_tokens: dict[str, str] | None = None,
) -> FastAPI:
    """The FastAPI application for ``settings``.

    :param clock: wall clock of the runner and scheduler (tests move it to age units).
    :param start_scheduler: start the drift scheduler's thread (tests call ``tick`` instead).
    :param extra_tokens: ``{secret: role}`` accepted besides ``settings.tokens`` (the
        admin token ``calbench serve`` generates when none is configured).
    """

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        services = build_services(settings, clock)
        for secret, role in (extra_tokens or {}).items():
            services.auth.add(secret, Role[role.upper()])
        app.state.services = services
        if start_scheduler and services.drift.time_of_day is not None:
            services.drift.start()
        try:
            with streams_end_on_signal(services.hub):
                yield
        finally:
            services.hub.close_all("the service is stopping")
            services.drift.stop()
            stopped = services.runner.shutdown()
            if stopped is not None:
                log.warning("run %s interrupted by the shutdown; resume it after the restart", stopped)
            services.auth.close()
            services.analysis.close()
            app.state.services = None
            services.engine.dispose()

    app = FastAPI(title="calbench", version="0.1.0", description=DESCRIPTION, lifespan=lifespan)
    app.include_router(api_router)
    if importlib.util.find_spec("api.routes.dashboard") is not None:
        app.include_router(importlib.import_module("api.routes.dashboard").router)
    if STATIC_DIR.is_dir():
        app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    return app
