"""Certificates of runs: JSON, PDF, and issuing one for a completed run."""

from __future__ import annotations

from typing import Any

import sqlalchemy as sa
from fastapi import APIRouter, HTTPException, Response, status

from api.deps import OperatorDep, SessionDep, SettingsDep, ViewerDep, ViewerLinkDep
from api.routes.views import certificate_out
from api.schemas import CertificateOut
from bench.fitted_model import ContractError, FittedModel
from db.models import Certificate, Unit
from db.repo.certificates import get_certificate_by_number
from db.repo.results import fit_contract
from db.repo.runs import get_run
from station.certificates.issue import (
    analyse_recording,
    form_budget,
    issue_for_run,
    store_diagnosis,
    store_g_before,
    unit_nominal,
)

router = APIRouter(tags=["certificates"])
_404: dict[int | str, dict[str, Any]] = {404: {"description": "no such run or no certificate"}}


def _of_run(session: SessionDep, run_id: str) -> tuple[Certificate, str]:
    row = session.execute(
        sa.select(Certificate, Unit.serial)
        .join(Unit, Certificate.unit_id == Unit.id)
        .where(Certificate.run_id == run_id)
        .order_by(Certificate.id.desc())
        .limit(1)
    ).first()
    if row is None:
        if get_run(session, run_id) is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} not found")
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} has no certificate")
    return row[0], row[1]


@router.get("/api/runs/{run_id}/certificate", response_model=CertificateOut, responses=_404)
def certificate(run_id: str, session: SessionDep, _: ViewerDep) -> CertificateOut:
    """The run's certificate: number, sha256 of the canonical JSON, and the content."""
    with session.begin():
        cert, serial = _of_run(session, run_id)
        return certificate_out(cert, serial, get_run(session, run_id))


@router.get(
    "/api/runs/{run_id}/certificate.pdf",
    response_class=Response,
    responses={200: {"content": {"application/pdf": {}}}, **_404},
)
def certificate_pdf(run_id: str, session: SessionDep, _: ViewerLinkDep) -> Response:
    """The run's certificate as PDF."""
    with session.begin():
        cert, _serial = _of_run(session, run_id)
        if cert.pdf is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, f"certificate {cert.number} has no PDF")
        return Response(
            cert.pdf,
            media_type="application/pdf",
            headers={"Content-Disposition": f'inline; filename="{cert.number}.pdf"'},
        )


@router.post(
    "/api/runs/{run_id}/certificate",
    status_code=status.HTTP_201_CREATED,
    response_model=CertificateOut,
    responses={
        404: {"description": "no such run"},
        409: {"description": "already issued"},
        422: {"description": "the run has no fit"},
    },
)
def issue(run_id: str, session: SessionDep, settings: SettingsDep, _: OperatorDep) -> CertificateOut:
    """Issue the certificate of a completed run that has none (e.g. one run from the CLI); a run
    not yet diagnosed is diagnosed first and its findings stored. The recording is read, fitted,
    diagnosed and its budget formed before the transaction that issues."""
    with session.begin():
        _issuable(session, run_id)
        run = get_run(session, run_id)
        assert run is not None
        path, diagnosed = run.recording_path, isinstance(run.diagnosis, dict)
        cal = fit_contract(session, run_id)
        g_check = cal.get("g_check", {}) if isinstance(cal, dict) else {}
        nominal = None if "before" in g_check else unit_nominal(session.get(Unit, run.unit_id))
        params = dict(run.params)
    prepared = analyse_recording(str(path) if path else None, nominal, diagnose=not diagnosed)
    stored = None
    if isinstance(cal, dict):
        try:
            stored = FittedModel.from_contract(cal, f"run {run_id}: stored fit")
        except ContractError:
            stored = None  # issue_for_run names the bad key
    if stored is not None:
        form_budget(prepared, settings, params, stored)
    with session.begin():
        serial = _issuable(session, run_id)
        store_g_before(session, run_id, prepared)
        if not diagnosed:
            store_diagnosis(session, run_id, prepared)
        try:
            cert = issue_for_run(session, settings, run_id, prepared=prepared, diagnosis_note=prepared.note)
        except ValueError as exc:
            raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(exc)) from None
        return certificate_out(cert, serial)


def _issuable(session: SessionDep, run_id: str) -> str:
    """The serial of the run's unit. :raises HTTPException: 404 no such run, 409 already issued."""
    run = get_run(session, run_id, with_unit=True)
    if run is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} not found")
    existing = session.scalar(sa.select(Certificate.number).where(Certificate.run_id == run_id))
    if existing is not None:
        raise HTTPException(status.HTTP_409_CONFLICT, f"run {run_id} already has certificate {existing}")
    return run.unit.serial


@router.get("/api/certificates/{number}", response_model=CertificateOut, responses=_404)
def by_number(number: str, session: SessionDep, _: ViewerDep) -> CertificateOut:
    """A certificate by its number, e.g. ``CB-2025-00001``."""
    with session.begin():
        cert = get_certificate_by_number(session, number)
        if cert is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, f"certificate {number} not found")
        serial = session.scalar(sa.select(Unit.serial).where(Unit.id == cert.unit_id))
        return certificate_out(cert, serial or "", get_run(session, cert.run_id))
