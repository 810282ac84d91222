"""Units: the list, registration (operator), and one unit's history (runs, certificates, drift checks)."""

from __future__ import annotations

from typing import Annotated

import sqlalchemy as sa
from fastapi import APIRouter, HTTPException, Path, Query, status

from api.deps import OperatorDep, RunnerDep, SessionDep, ViewerDep
from api.routes.views import certificate_out, drift_out, run_out
from api.schemas import MAX_PAGE_OFFSET, SERIAL_PATTERN, UnitHistory, UnitOut, UnitRegistration
from db.models import Bench, Certificate, DriftCheck, Run, Unit
from db.repo.certificates import list_certificates
from db.repo.drift import list_drift_checks
from db.repo.results import results_of_runs
from db.repo.runs import list_runs
from db.repo.units import get_or_create_unit, get_unit_by_serial, list_units

router = APIRouter(prefix="/api/units", tags=["units"])


def _unit_out(session: SessionDep, unit: Unit) -> UnitOut:
    bench = session.scalar(sa.select(Bench.name).where(Bench.id == unit.bench_id)) if unit.bench_id else None
    n_runs = session.scalar(sa.select(sa.func.count()).select_from(Run).where(Run.unit_id == unit.id)) or 0
    last_cert = session.scalar(
        sa.select(Certificate.number).where(Certificate.unit_id == unit.id).order_by(Certificate.id.desc())
    )
    last_drift = session.scalar(
        sa.select(DriftCheck.flagged).where(DriftCheck.unit_id == unit.id).order_by(DriftCheck.id.desc())
    )
    return UnitOut(
        serial=unit.serial,
        model=unit.model,
        channel_unit=unit.channel_unit,
        bench=bench,
        n_runs=int(n_runs),
        last_certificate=last_cert,
        last_drift_flagged=last_drift,
        **{name: getattr(unit, name) for name in REGISTRATION_FIELDS},
    )


REGISTRATION_FIELDS = (
    "description",
    "customer_name",
    "customer_address",
    "received_on",
    "nominal_scale",
    "nominal_bias",
    "condition",
)


@router.get("", response_model=list[UnitOut])
def units(
    session: SessionDep,
    _: ViewerDep,
    q: Annotated[
        str | None, Query(max_length=64, description="text in the serial, model or customer")
    ] = None,
    limit: Annotated[int | None, Query(ge=1, le=1000, description="at most this many (paging)")] = None,
    offset: Annotated[
        int, Query(ge=0, le=MAX_PAGE_OFFSET, description="units skipped from the first by serial (paging)")
    ] = 0,
) -> list[UnitOut]:
    """Units by serial, with their last certificate and whether their last drift check flagged
    them; filtered by a text in the serial, model or customer (``q``), paged by ``limit`` and
    ``offset`` (every unit without them)."""
    with session.begin():
        return [_unit_out(session, u) for u in list_units(session, search=q, limit=limit, offset=offset)]


@router.put(
    "/{serial}",
    response_model=UnitOut,
    responses={422: {"description": "a bad field or serial, named"}},
)
def register(
    serial: Annotated[str, Path(pattern=SERIAL_PATTERN)],
    body: UnitRegistration,
    session: SessionDep,
    _: OperatorDep,
) -> UnitOut:
    """Register a unit or update what the laboratory states about it (customer, date of
    receipt, model, nominal scale...); these go on its next certificates. Fields not sent
    keep their value, ``null`` clears one."""
    with session.begin():
        unit = get_or_create_unit(session, serial)
        for name in body.model_fields_set:
            setattr(unit, name, getattr(body, name))
        session.flush()
        return _unit_out(session, unit)


@router.get("/{serial}/history", response_model=UnitHistory, responses={404: {"description": "no such unit"}})
def history(serial: str, session: SessionDep, runner: RunnerDep, _: ViewerDep) -> UnitHistory:
    """A unit's runs (with their fits), certificates and drift checks, oldest first."""
    with session.begin():
        unit = get_unit_by_serial(session, serial)
        if unit is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, f"unit {serial} not found")
        certs = list_certificates(session, unit.id)
        by_run = {c.run_id: c.number for c in certs}
        by_id = {c.id: c.number for c in certs}
        runs = list(reversed(list_runs(session, unit_serial=serial)))
        results = results_of_runs(session, [r.id for r in runs])
        run_by_id = {r.id: r for r in runs}
        return UnitHistory(
            unit=_unit_out(session, unit),
            runs=[
                run_out(r, serial, runner.live(r.id), by_run.get(r.id), results=results[r.id]) for r in runs
            ],
            certificates=[certificate_out(c, serial, run_by_id.get(c.run_id)) for c in certs],
            drift_checks=[
                drift_out(d, serial, by_id.get(d.reference_certificate_id or -1))
                for d in list_drift_checks(session, unit.id)
            ],
        )
