"""Drift checks: the scheduler's state, running a check now, and the stored results."""

from __future__ import annotations

from typing import Annotated

import sqlalchemy as sa
from fastapi import APIRouter, HTTPException, Query, status

from api.deps import OperatorDep, ServicesDep, SessionDep, ViewerDep
from api.routes.views import drift_out
from api.schemas import DriftCheckOut, DriftNotChecked, DriftRequest, DriftStatus
from db.models import Certificate, DriftCheck, Unit
from station.drift import drift_checks_in_queue

router = APIRouter(prefix="/api/drift", tags=["drift"])


def _status(services: ServicesDep, session: SessionDep) -> DriftStatus:
    d, s = services.drift, services.settings
    with session.begin():
        waiting, holding = drift_checks_in_queue(session)
    return DriftStatus(
        enabled=d.time_of_day is not None,
        time_of_day=d.time_of_day.strftime("%H:%M") if d.time_of_day else None,
        next_run_at=d.next_run_at,
        last_run_at=d.last_run_at,
        procedure=s.drift_procedure,
        dwell_s=s.drift_dwell_s,
        k=s.drift_k,
        running=bool(holding),
        pending_units=waiting,
        not_checked=[
            DriftNotChecked(unit_serial=n.unit_serial, bench=n.bench, reason=n.reason)
            for n in sorted(d.not_checked.values(), key=lambda n: n.unit_serial)
        ],
    )


@router.get("", response_model=DriftStatus)
def drift_status(services: ServicesDep, session: SessionDep, _: ViewerDep) -> DriftStatus:
    """When the nightly check runs next, what it runs, which units' checks wait in their benches'
    queues, and which units were not checked (their bench has no live agent or cannot run the
    procedure), with the reason."""
    return _status(services, session)


@router.post(
    "/run",
    status_code=status.HTTP_202_ACCEPTED,
    response_model=DriftStatus,
    responses={404: {"description": "no such unit"}},
)
def run_now(body: DriftRequest, services: ServicesDep, session: SessionDep, _: OperatorDep) -> DriftStatus:
    """Queue the drift check now for one unit or every unit with a certificate, each on its
    unit's bench; each bench's agent runs its checks one after the other."""
    try:
        services.drift.enqueue(body.unit_serial)
    except LookupError as exc:
        raise HTTPException(status.HTTP_404_NOT_FOUND, str(exc)) from None
    return _status(services, session)


@router.get("/checks", response_model=list[DriftCheckOut])
def checks(
    session: SessionDep,
    _: ViewerDep,
    flagged: bool | None = None,
    unit_serial: Annotated[str | None, Query(max_length=64)] = None,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
) -> list[DriftCheckOut]:
    """Stored drift checks, newest first; ``flagged=true`` for the units that moved."""
    stmt = (
        sa.select(DriftCheck, Unit.serial, Certificate.number)
        .join(Unit, DriftCheck.unit_id == Unit.id)
        .outerjoin(Certificate, DriftCheck.reference_certificate_id == Certificate.id)
        .order_by(DriftCheck.checked_at.desc(), DriftCheck.id.desc())
        .limit(limit)
    )
    if flagged is not None:
        stmt = stmt.where(DriftCheck.flagged.is_(flagged))
    if unit_serial is not None:
        stmt = stmt.where(Unit.serial == unit_serial)
    with session.begin():
        return [drift_out(c, serial, number) for c, serial, number in session.execute(stmt).all()]
