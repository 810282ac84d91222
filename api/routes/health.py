"""Liveness (no token needed) and the caller's role."""

from __future__ import annotations

import sqlalchemy as sa
from fastapi import APIRouter

from api.deps import ServicesDep, ViewerDep
from api.schemas import Health, WhoAmI

router = APIRouter(prefix="/api", tags=["health"])
VERSION = "0.1.0"


@router.get("/health", response_model=Health)
def health(services: ServicesDep) -> Health:
    """Is the service up, is its database reachable, is the bench busy."""
    ok = True
    try:
        with services.read_sessions.begin() as s:
            s.execute(sa.text("SELECT 1"))
    except sa.exc.SQLAlchemyError:
        ok = False
    cur = services.runner.current
    blocking, warnings = services.settings.certificate_gaps()
    return Health(
        status="ok" if ok else "degraded",
        version=VERSION,
        bench=services.settings.bench_name,
        simulated=services.settings.sim,
        database=services.engine.url.get_backend_name(),
        database_ok=ok,
        busy_run=cur.id if cur is not None else None,
        public_read=services.auth.public_read,
        certificate_problems=blocking + warnings,
        certificates_blocked=bool(blocking) and not services.settings.sim,
        worker=services.worker_id,
        live_updates="notify" if services.wakeups.listening else "poll",
    )


@router.get("/whoami", response_model=WhoAmI)
def whoami(role: ViewerDep) -> WhoAmI:
    """The role of the presented token (``anonymous`` where reads are public)."""
    return WhoAmI(role=role.label)
