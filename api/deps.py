"""FastAPI dependencies: the service's parts, a session per request, and the role checks.

Routes take ``SessionDep`` and open the transaction themselves (``with session.begin():``);
repo functions only add, flush and select. A ``GET``/``HEAD`` request gets a read-only session
(on SQLite a deferred transaction that an open write transaction does not block); every
other method gets a writing one (``BEGIN IMMEDIATE`` on SQLite).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated

from fastapi import Depends, HTTPException, Query, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session, sessionmaker

from api.analysis_worker import AnalysisPool
from api.auth import Authenticator, AuthError, Role
from api.drift import DriftScheduler
from api.progress_hub import ProgressHub
from api.run_queue import RunQueue
from api.settings import Settings

if TYPE_CHECKING:
    from api.agent import BenchAgent
    from api.run_events import SnapshotCache


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


def _check(services: Services, secret: str | None, minimum: Role) -> Role:
    try:
        return services.auth.require(secret, minimum)
    except AuthError as exc:
        headers = {"WWW-Authenticate": "Bearer"} if exc.status_code == 401 else None
        raise HTTPException(exc.status_code, str(exc), headers=headers) from None


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


def require_viewer_or_query(
    services: ServicesDep,
    creds: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
    access_token: Annotated[
        str | None, Query(max_length=200, description="token, for links a browser opens directly")
    ] = None,
) -> Role:
    """A viewer token in the header or in ``?access_token=`` (event stream, PDF)."""
    secret = creds.credentials if creds else access_token
    return _check(services, secret, Role.VIEWER)


def require_admin(
    services: ServicesDep, creds: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]
) -> Role:
    """An admin token (token management)."""
    return _check(services, creds.credentials if creds else None, Role.ADMIN)


ViewerDep = Annotated[Role, Depends(require_viewer)]
AdminDep = Annotated[Role, Depends(require_admin)]
OperatorDep = Annotated[Role, Depends(require_operator)]
ViewerLinkDep = Annotated[Role, Depends(require_viewer_or_query)]
