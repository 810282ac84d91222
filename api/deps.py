"""FastAPI dependencies: the service's parts, a session per request, and the role checks.

Routes take ``SessionDep`` and open the transaction themselves (``with session.begin():``);
repo functions only add, flush and select. A ``GET``/``HEAD`` request gets a read-only session
(on SQLite a deferred transaction that an open write transaction does not block); every
other method gets a writing one (``BEGIN IMMEDIATE`` on SQLite).
"""

from __future__ import annotations

import secrets
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated

from fastapi import Depends, HTTPException, Query, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session, sessionmaker

from api.auth import Authenticator, AuthError, Principal, Role
from api.runs.wakeup import RunWakeups
from station.analysis_worker import AnalysisPool
from station.drift import DriftScheduler
from station.runs.hub import ProgressHub
from station.runs.queue import RunQueue
from station.settings import Settings

if TYPE_CHECKING:
    from api.doc_cache import DocumentStore
    from api.runs.events import SnapshotCache
    from station.agent.bench_agent import BenchAgent


@dataclass
class Services:
    """What the app's lifespan builds and the routes use."""

    settings: Settings
    engine: Engine
    sessions: sessionmaker[Session]
    read_sessions: sessionmaker[Session]
    hub: ProgressHub
    runner: RunQueue
    drift: DriftScheduler
    auth: Authenticator
    analysis: AnalysisPool = field(default_factory=lambda: AnalysisPool(0))
    agent: BenchAgent | None = None
    """The bench agent running in this process (``settings.agent == "embedded"``), else ``None``."""
    snapshots: SnapshotCache | None = None
    """The runs' snapshots shared by this process's event streams (``None``: one per stream)."""
    wakeups: RunWakeups = field(default_factory=RunWakeups)
    """Wakes this process's event streams when a run changes (PostgreSQL notifications)."""
    worker_id: str = field(default_factory=lambda: secrets.token_hex(4))
    """Random id of this API process (``X-Calbench-Worker``), to tell workers apart."""
    documents: DocumentStore | None = None
    """The dashboard's documents kept per database revision (:mod:`api.doc_cache`; ``None``: none)."""


def get_services(request: Request) -> Services:
    """The services of the running app (set by its lifespan)."""
    services: Services | None = getattr(request.app.state, "services", None)
    if services is None:
        raise HTTPException(503, "the service is starting or stopping")
    return services


ServicesDep = Annotated[Services, Depends(get_services)]


READ_METHODS = frozenset({"GET", "HEAD"})


def get_session(request: Request, services: ServicesDep) -> Iterator[Session]:
    """A session for the request (read-only for ``GET``/``HEAD``); the route opens the transaction."""
    factory = services.read_sessions if request.method in READ_METHODS else services.sessions
    with factory() as session:
        yield session


SessionDep = Annotated[Session, Depends(get_session)]


def get_settings(services: ServicesDep) -> Settings:
    """The service's settings."""
    return services.settings


def get_runner(services: ServicesDep) -> RunQueue:
    """The bench's run queue."""
    return services.runner


SettingsDep = Annotated[Settings, Depends(get_settings)]
RunnerDep = Annotated[RunQueue, Depends(get_runner)]

_bearer = HTTPBearer(auto_error=False, description="a viewer, operator or admin token")


def _http(exc: AuthError) -> HTTPException:
    headers = {"WWW-Authenticate": "Bearer"} if exc.status_code == 401 else None
    return HTTPException(exc.status_code, str(exc), headers=headers)


def _check(services: Services, secret: str | None, minimum: Role) -> Role:
    try:
        return services.auth.require(secret, minimum)
    except AuthError as exc:
        raise _http(exc) from None


def require_viewer_principal(
    services: ServicesDep, creds: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]
) -> Principal:
    """At least a viewer token, as the principal (token id) it belongs to."""
    try:
        return services.auth.require_principal(creds.credentials if creds else None, Role.VIEWER)
    except AuthError as exc:
        raise _http(exc) from None


def require_viewer(
    services: ServicesDep, creds: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]
) -> Role:
    """At least a viewer token (none needed with ``public_read``)."""
    return _check(services, creds.credentials if creds else None, Role.VIEWER)


def require_operator(
    services: ServicesDep, creds: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]
) -> Role:
    """An operator (or admin) token."""
    return _check(services, creds.credentials if creds else None, Role.OPERATOR)


def require_operator_principal(
    services: ServicesDep, creds: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]
) -> Principal:
    """An operator (or admin) token, as the principal it belongs to (its operator's name goes into
    the audit trail of the run it acts on)."""
    try:
        return services.auth.require_principal(creds.credentials if creds else None, Role.OPERATOR)
    except AuthError as exc:
        raise _http(exc) from None


def require_viewer_or_link(
    request: Request,
    services: ServicesDep,
    creds: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
    link: Annotated[
        str | None,
        Query(
            max_length=2000, description="a signed link from POST /api/links (a browser opens it directly)"
        ),
    ] = None,
) -> Principal:
    """A viewer token in the header, or a link signed for this path (event stream, PDF) whose
    token is still live. The caller's token never travels in the URL."""
    if creds is not None or link is None:
        try:
            return services.auth.require_principal(creds.credentials if creds else None, Role.VIEWER)
        except AuthError as exc:
            raise _http(exc) from None
    try:
        who = services.auth.links.verify(link, request.url.path)
    except AuthError as exc:
        raise _http(exc) from None
    if not services.auth.is_live(who):
        raise _http(AuthError(401, "the token this link was made for has been revoked"))
    return who


def require_admin(
    services: ServicesDep, creds: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]
) -> Role:
    """An admin token (token management)."""
    return _check(services, creds.credentials if creds else None, Role.ADMIN)


ViewerDep = Annotated[Role, Depends(require_viewer)]
AdminDep = Annotated[Role, Depends(require_admin)]
OperatorDep = Annotated[Role, Depends(require_operator)]
OperatorPrincipalDep = Annotated[Principal, Depends(require_operator_principal)]
ViewerLinkDep = Annotated[Principal, Depends(require_viewer_or_link)]
ViewerPrincipalDep = Annotated[Principal, Depends(require_viewer_principal)]
