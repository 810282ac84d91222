"""The service: ``create_app(settings)`` wires database, run queue, drift scheduler, auth, routes.

The API never drives the bench itself: runs and control requests go to the database
(:class:`station.runs.queue.RunQueue`) and the bench's agent (:mod:`station.agent.bench_agent`) executes them.
With ``settings.agent == "external"`` the agent is another process (``calbench agent``,
started by ``calbench serve`` or by docker compose); with ``"embedded"`` (the default of
``create_app``: tests, a one-process set-up) the lifespan runs one in a thread of this process,
through the same queue, and on shutdown leaves the run it holds ``interrupted`` — table safe,
recording closed, resumable with ``POST /api/runs/{id}/resume`` after the restart.

The lifespan opens (creates and migrates) the database, marks runs left live by a dead
process ``interrupted`` (and runs a previous shutdown stopped, see
:mod:`station.runs.resume`), starts the drift scheduler's thread and, on PostgreSQL, the
listener that wakes this process's event streams when a run changes (:mod:`db.notify`,
:mod:`api.runs.wakeup`). The process keeps no state of its own that another API process would
miss: runs, queue, live progress and events are all in the database, so ``calbench serve
--workers N`` runs N of them. On SIGTERM/SIGINT
the open event streams end first, so the server does not wait for them before stopping.
Nothing is read from the environment here: the caller builds ``Settings`` (``calbench
serve`` does, from ``CALBENCH_*``).

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
from types import FrameType

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

from api.auth import Authenticator, Role, parse_token_names, parse_tokens
from api.db_revision import DatabaseRevision
from api.deps import Services
from api.doc_cache import DocumentCache, DocumentStore
from api.error_handlers import install_error_handlers
from api.guard import RequestGuard
from api.log_redaction import install_log_redaction
from api.routes import api_router
from api.runs.events import SnapshotCache
from api.runs.wakeup import RunWakeups
from api.startup_check import check_configuration
from bench.records import utc_now
from db.engine import make_session_factory
from db.migrate import open_database
from db.notify import RunListener, listen_url
from db.repo.recovery import mark_interrupted_runs
from station.agent.bench_agent import BenchAgent
from station.analysis_worker import AnalysisPool
from station.drift import DriftScheduler
from station.runs.hub import ProgressHub
from station.runs.queue import RunQueue
from station.runs.resume import recover_shutdown_aborts
from station.settings import Settings

log = logging.getLogger(__name__)
STATIC_DIR = Path(__file__).resolve().parent / "static"
DESCRIPTION = """Accelerometer calibration bench service.

Roles: a **viewer** token reads, an **operator** token also starts and aborts runs, issues
certificates, uploads recordings and starts drift checks. Send `Authorization: Bearer TOKEN`.
Missing or unknown token: 401; a role too low: 403. One run at a time per bench: a second
start gets 409. A request with a body is authenticated, and its size checked (1 MB of JSON,
1 GB of upload: 413), before the body is read. A browser opens a PDF or an event stream with
a short-lived signed link (`POST /api/links`), never with a token in the URL.
"""


def build_services(settings: Settings, clock: Callable[[], dt.datetime] = utc_now) -> Services:
    """Open the database (migrating it) and build the run queue, scheduler and authenticator.

    :raises ValueError: a malformed ``CALBENCH_TOKENS`` entry or ``CALBENCH_DRIFT_TIME``, or a
        configuration :func:`api.startup_check.check_configuration` refuses (device URL, database file).
    """
    check_configuration(settings)
    env_tokens = parse_tokens(settings.tokens)
    engine = open_database(settings.effective_database_url)
    sessions = make_session_factory(engine)
    read_sessions = make_session_factory(engine, read_only=True)
    with sessions.begin() as s:
        marked = mark_interrupted_runs(s, socket.gethostname()) + recover_shutdown_aborts(s)
    if marked:
        log.warning("runs left live by a dead process, now interrupted: %s", ", ".join(marked))
    blocking, warnings = settings.certificate_gaps()
    for gap in blocking:
        if settings.sim:
            log.warning("certificate: %s; the simulated bench's certificates say so", gap)
        else:
            log.error("certificate: %s; this bench issues no certificate until it is set", gap)
    for gap in warnings:
        log.warning("certificate: %s", gap)
    hub = ProgressHub()
    runner = RunQueue(settings, sessions, read_sessions, clock=clock)
    drift = DriftScheduler(settings, sessions, runner, clock=clock)
    auth = Authenticator(
        env_tokens,
        sessions,
        read_sessions,
        public_read=settings.public_read,
        link_key=settings.link_key.encode("utf-8") or None,
        env_names=parse_token_names(settings.tokens),
    )
    analysis = AnalysisPool(settings.upload_workers)
    snapshots = SnapshotCache(read_sessions)
    return Services(
        settings,
        engine,
        sessions,
        read_sessions,
        hub,
        runner,
        drift,
        auth,
        analysis,
        snapshots=snapshots,
        wakeups=RunWakeups(on_notify=snapshots.invalidate),
        documents=DocumentStore(DatabaseRevision(engine.url)),
    )


def end_streams(services: Services, reason: str) -> None:
    """End every open event stream of this process with a ``shutdown`` event (``reason``)."""
    services.hub.close_all(reason)
    services.wakeups.wake_all()


def start_listener(settings: Settings, services: Services) -> RunListener | None:
    """On PostgreSQL, a :class:`db.notify.RunListener` that wakes this process's event streams
    when a run changes (in any process); ``None`` on SQLite, where the streams poll."""
    conninfo = listen_url(settings.effective_database_url)
    if conninfo is None:
        return None
    listener = RunListener(conninfo, services.wakeups.notify, services.wakeups.set_listening)
    listener.start()
    return listener


SignalHandler = Callable[[int, FrameType | None], object] | int | signal.Handlers | None
"""What ``signal.getsignal`` returns (``None``: a handler not installed from Python)."""


@contextmanager
def streams_end_on_signal(services: Services) -> Iterator[None]:
    """While the server runs, SIGTERM and SIGINT first end every open event stream, then go to
    the server's own handler (which waits for open responses before the lifespan's shutdown
    stops the run). Outside the main thread (a test client) nothing is installed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    loop = asyncio.get_running_loop()
    previous: dict[signal.Signals, SignalHandler] = {}

    def handler(signum: int, frame: FrameType | None) -> None:
        reason = f"the service is stopping ({signal.Signals(signum).name})"
        loop.call_soon_threadsafe(end_streams, services, reason)
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
            # getsignal gives None for a handler not installed from Python: the default then
            signal.signal(sig, signal.SIG_DFL if prev is None else prev)


def create_app(
    settings: Settings,
    *,
    clock: Callable[[], dt.datetime] = utc_now,
    start_scheduler: bool = True,
    extra_tokens: dict[str, str] | None = None,
    on_shutdown: Callable[[], None] | None = None,
) -> FastAPI:
    """The FastAPI application for ``settings``.

    :param clock: wall clock of the runner and scheduler (tests move it to age units).
    :param start_scheduler: start the drift scheduler's thread (tests call ``tick`` instead).
    :param extra_tokens: ``{secret: role}`` accepted besides ``settings.tokens`` (the
        admin token ``calbench serve`` generates when none is configured).
    :param on_shutdown: called at the end of the lifespan (``calbench serve`` stops the bench
        agent it started there: after a signal the server re-raises it once the lifespan is over).
    """

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        install_log_redaction()  # after the server configured its logging
        services = build_services(settings, clock)
        for secret, role in (extra_tokens or {}).items():
            services.auth.add(secret, Role[role.upper()], f"{role} token generated at start")
        agent = None
        if settings.agent == "embedded":
            agent = BenchAgent(settings, clock=clock)
            agent.start()
        services.agent = agent
        listener = start_listener(settings, services)
        services.analysis.warm()
        app.state.services = services
        if start_scheduler and services.drift.time_of_day is not None:
            services.drift.start()
        try:
            with streams_end_on_signal(services):
                yield
        finally:
            end_streams(services, "the service is stopping")
            if listener is not None:
                listener.stop()
            services.drift.stop()
            if agent is not None:
                agent.stop()
                agent.close()
            if on_shutdown is not None:
                on_shutdown()
            services.auth.close()
            services.analysis.close()
            app.state.services = None
            if services.documents is not None:
                services.documents.close()
            services.engine.dispose()

    app = FastAPI(title="calbench", version="0.1.0", description=DESCRIPTION, lifespan=lifespan)
    app.add_middleware(DocumentCache)
    app.add_middleware(RequestGuard)  # outermost: it heads every answer
    install_error_handlers(app)
    app.include_router(api_router)
    if importlib.util.find_spec("api.routes.dashboard") is not None:
        app.include_router(importlib.import_module("api.routes.dashboard").router)
    if STATIC_DIR.is_dir():
        app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    return app
