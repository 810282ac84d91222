"""JSON series for the dashboard's plots, and a run's diagnosis as stored.

Read-only (viewer role). A run's series come from its recording and fit
(:mod:`api.plots.run_bundle`), so they exist once the run is final and has a fit:
a run still recording gets 409, a run without a fit 409 naming its state, a
recording that has gone missing or cannot be read 422 naming the file.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query, Response, status
from fastapi.responses import FileResponse
from sqlalchemy.orm import Session

from api.deps import SessionDep, ViewerDep, ViewerLinkDep
from api.exports import certified_uncertainty, export_text
from api.plots.history_series import HistoryPoint, coefficient_history
from api.plots.run_bundle import BundleCache, RunBundle, build_bundle
from api.plots.run_series import PreviousCalibration
from bench.export import FORMATS, MEDIA_TYPES, SUFFIX
from bench.fitted_model import ContractError, FittedModel
from bench.recording.reader import sidecar_path_for
from db.models import ACTIVE_STATES, Run
from db.repo.certificates import certificate_of_run
from db.repo.progress import list_windows
from db.repo.results import fit_contract, fit_contracts
from db.repo.runs import get_run, list_runs
from db.repo.units import get_unit_by_serial
from db.types import unreadable_reason

router = APIRouter(tags=["plots"])
CACHE = BundleCache()
_404: dict[int | str, dict[str, Any]] = {404: {"description": "no such run"}}
_ERRORS: dict[int | str, dict[str, Any]] = {
    **_404,
    409: {"description": "the run is live or has no fit"},
    422: {"description": "the recording cannot be read or fitted"},
}


def _final_run(session: Session, run_id: str) -> Run:
    run = get_run(session, run_id)
    if run is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} not found")
    if run.state in ACTIVE_STATES:
        raise HTTPException(
            status.HTTP_409_CONFLICT, f"run {run_id} is {run.state.value}: no plots until it ends"
        )
    if not isinstance(fit_contract(session, run_id), dict):
        raise HTTPException(
            status.HTTP_409_CONFLICT, f"run {run_id} is {run.state.value} without a fit: nothing to plot"
        )
    if not run.recording_path:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, f"run {run_id} has no recording path")
    return run


def _bundle(session: Session, run_id: str) -> tuple[str, RunBundle]:
    with session.begin():
        run = _final_run(session, run_id)
        path = str(run.recording_path)
        noise = [(w.start_s, w.end_s) for w in list_windows(session, run_id) if w.kind == "noise"]
    try:
        key = CACHE.key(run_id, path)
        return path, CACHE.get(key, lambda: build_bundle(path, noise))
    except OSError as exc:
        raise HTTPException(
            status.HTTP_422_UNPROCESSABLE_CONTENT, f"run {run_id}: recording {path} cannot be read: {exc}"
        ) from None
    except ValueError as exc:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, f"run {run_id}: {exc}") from None


def _registered_nominal(session: Session, run_id: str) -> tuple[float | None, list[float] | None]:
    """The run's unit's registered nominal scale and zero-g output (``None`` when not known)."""
    with session.begin():
        run = get_run(session, run_id, with_unit=True)
        unit = run.unit if run is not None else None
        if unit is None or unit.nominal_scale is None:
            return None, None
        bias = None if unit.nominal_bias is None else [float(unit.nominal_bias)] * 3
        return float(unit.nominal_scale), bias


def stored_fit(run_id: str, contract: object) -> FittedModel:
    """The run's stored fit (``contract``: its ``fit_model`` row's object), parsed.

    :raises ContractError: the stored object lacks a key or holds an ill-typed one (named).
    """
    return FittedModel.from_contract(contract, f"run {run_id}: stored fit")


def _previous_calibration(session: Session, run_id: str) -> PreviousCalibration | None:
    """The unit's last calibrated run before ``run_id`` whose stored fit can be read."""
    with session.begin():
        run = get_run(session, run_id, with_unit=True)
        if run is None:
            return None
        earlier = [
            other
            for other in list_runs(session, unit_serial=run.unit.serial)  # newest first
            if other.id != run_id and other.created_at < run.created_at
        ]
        fits = fit_contracts(session, [other.id for other in earlier])
        for other in earlier:
            if not isinstance(fits.get(other.id), dict):
                continue
            try:
                return PreviousCalibration(other.id, stored_fit(other.id, fits[other.id]))
            except ContractError:
                continue
    return None


@router.get("/api/runs/{run_id}/plots/g-check", responses=_ERRORS)
def g_check(
    run_id: str,
    session: SessionDep,
    _: ViewerDep,
    nominal_scale: Annotated[
        float | None, Query(description="datasheet sensitivity (channel unit per m/s²) for 'before'")
    ] = None,
    nominal_bias: Annotated[
        list[float] | None, Query(description="datasheet zero-g output, 3 values (channel unit)")
    ] = None,
) -> dict[str, Any]:
    """|f̂| per static window after correction, and before: with the nominal scale (given, else
    the unit's registered one, which the fit's own 'before' check used; natural for m/s² and g
    channels) or else with the unit's previous calibration."""
    bundle = _bundle(session, run_id)[1]
    if nominal_scale is None:
        nominal_scale, nominal_bias = _registered_nominal(session, run_id)
    previous = None if nominal_scale is not None else _previous_calibration(session, run_id)
    try:
        return bundle.g_check(nominal_scale, nominal_bias, previous)
    except ValueError as exc:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(exc)) from None


@router.get("/api/runs/{run_id}/plots/residuals", responses=_ERRORS)
def residuals(run_id: str, session: SessionDep, _: ViewerDep) -> dict[str, Any]:
    """Fit residuals per static window and channel (channel units and z-scores)."""
    return _bundle(session, run_id)[1].residuals


@router.get("/api/runs/{run_id}/plots/allan", responses=_ERRORS)
def allan(run_id: str, session: SessionDep, _: ViewerDep) -> dict[str, Any]:
    """Overlapping Allan deviation of the run's noise window (or longest static window)."""
    bundle = _bundle(session, run_id)[1]
    if bundle.allan is None:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, bundle.allan_error or "no Allan curve")
    return bundle.allan


@router.get("/api/runs/{run_id}/diagnosis", responses=_404)
def diagnosis(run_id: str, session: SessionDep, _: ViewerDep) -> dict[str, Any]:
    """The run's stored diagnosis (the ``calbench diagnose --json`` object) or why there is none:
    ``{"run_id", "diagnosis": {...} | null, "note": str}``."""
    with session.begin():
        run = get_run(session, run_id)
        if run is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} not found")
        diag = run.diagnosis
        note = str(run.diagnosis_error or unreadable_reason(diag) or "")
        if not isinstance(diag, dict) or unreadable_reason(diag) is not None:
            diag = None
            if not note:
                note = (
                    f"run is {run.state.value}: diagnosis comes after the fit"
                    if run.state in ACTIVE_STATES
                    else "no diagnosis stored for this run"
                )
        return {"run_id": run_id, "diagnosis": diag, "note": note}


@router.get("/api/units/{serial}/plots/history", responses={404: {"description": "no such unit"}})
def history(serial: str, session: SessionDep, _: ViewerDep) -> dict[str, Any]:
    """Every fitted coefficient of the unit over its calibrated runs, with U = 2σ of the fit's Type A σ;
    a run whose stored fit cannot be read is listed under ``unreadable_fits`` with the key at fault."""
    with session.begin():
        unit = get_unit_by_serial(session, serial)
        if unit is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, f"unit {serial} not found")
        points = []
        unreadable = []
        runs = list_runs(session, unit_serial=serial)
        fits = fit_contracts(session, [run.id for run in runs])
        for run in runs:
            if not isinstance(fits.get(run.id), dict):
                continue
            try:
                fit = stored_fit(run.id, fits[run.id])
            except ContractError as exc:
                unreadable.append({"run_id": run.id, "error": str(exc)})
                continue
            when = run.finished_at or run.started_at or run.created_at
            kind = str(run.kind or "other")
            points.append(HistoryPoint(run.id, when.isoformat() if when else "", fit, kind))
        channel_unit = unit.channel_unit or "?"
    out = coefficient_history(points, channel_unit)
    out["unit_serial"] = serial
    out["channel_unit"] = channel_unit
    if unreadable:
        out["unreadable_fits"] = unreadable
    return out


@router.get(
    "/api/runs/{run_id}/export/{fmt}",
    response_class=Response,
    responses={**_ERRORS, 200: {"content": {m: {} for m in set(MEDIA_TYPES.values())}}},
)
def export(run_id: str, fmt: str, session: SessionDep, _: ViewerLinkDep) -> Response:
    """The run's stored fit (the certificate's values) for another tool: ``imucal`` (imucal's
    calibration JSON), ``kalibr`` (Kalibr-style IMU YAML with noise from the run's Allan
    curve), ``c-header`` (C99 firmware header) or ``json`` (``calbench-correction/1``); a certified
    run's export states the certificate's number, date and expanded uncertainties."""
    if fmt not in FORMATS:
        raise HTTPException(
            status.HTTP_404_NOT_FOUND, f"unknown export format {fmt!r}; known: {', '.join(FORMATS)}"
        )
    with session.begin():
        _final_run(session, run_id)
        try:
            fit = stored_fit(run_id, fit_contract(session, run_id))
        except ContractError as exc:
            raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(exc)) from None
        cert = certificate_of_run(session, run_id)
        certified = (cert.number, cert.issued_at, cert.content) if cert is not None else None
    fit = replace(fit, unit_serial=fit.unit_serial or run_id)
    allan = _bundle(session, run_id)[1].allan if fmt == "kalibr" else None
    try:
        u = certified_uncertainty(*certified) if certified is not None else None
        text = export_text(fmt, fit, allan, f"run {run_id}", u)
    except ValueError as exc:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, f"run {run_id}: {exc}") from None
    name = f"{run_id}{SUFFIX[fmt]}"
    return Response(
        text, media_type=MEDIA_TYPES[fmt], headers={"Content-Disposition": f'attachment; filename="{name}"'}
    )


RECORDING_PARTS = {"csv": ("", "text/csv"), "sidecar": (".json", "application/json")}
"""The parts of a raw recording: the samples (CSV) and the sidecar beside it (JSON)."""


@router.get(
    "/api/runs/{run_id}/recording/{part}",
    response_class=FileResponse,
    responses={
        **_404,
        409: {"description": "the run is live: its recording is still being written"},
        422: {"description": "the run has no recording on this host"},
        200: {"content": {"text/csv": {}, "application/json": {}}},
    },
)
def recording(run_id: str, part: str, session: SessionDep, _: ViewerLinkDep) -> FileResponse:
    """The run's raw recording as stored on the bench: ``csv`` (the samples) or ``sidecar`` (its
    JSON description: channels, rates, windows, geometry), for analysis in other tools."""
    if part not in RECORDING_PARTS:
        raise HTTPException(
            status.HTTP_404_NOT_FOUND, f"unknown recording part {part!r}; known: {', '.join(RECORDING_PARTS)}"
        )
    with session.begin():
        run = get_run(session, run_id)
        if run is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} not found")
        if run.state in ACTIVE_STATES:
            raise HTTPException(
                status.HTTP_409_CONFLICT,
                f"run {run_id} is {run.state.value}: its recording is still being written",
            )
        path = run.recording_path
    if not path:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, f"run {run_id} has no recording path")
    csv_path = Path(path)
    file = sidecar_path_for(csv_path) if part == "sidecar" else csv_path
    if not file.is_file():
        raise HTTPException(
            status.HTTP_422_UNPROCESSABLE_CONTENT, f"run {run_id}: {file.name} is not on this host"
        )
    return FileResponse(file, media_type=RECORDING_PARTS[part][1], filename=f"{run_id}{file.suffix}")
