"""What a procedure will do before it is started: duration, poses, windows, dwell, and which
model terms its motion determines."""

from __future__ import annotations

import functools
import json
import math
from typing import Annotated

from fastapi import APIRouter, HTTPException, Query, status

from api.deps import SessionDep, SettingsDep, ViewerDep
from api.schemas import SERIAL_PATTERN, ProcedurePreviewOut
from bench.bench_config import BenchConfigError
from bench.estimation.dynamic_model import TERM_ORDER
from bench.procedures import (
    Admitted,
    Preview,
    Refusal,
    RefusalKind,
    TableLimits,
    build_procedure,
    check_procedure,
)
from bench.procedures.observability import plan_observability
from bench.procedures.preview import provisional_dwell
from station.certificates.conformity import unit_warnings
from station.execution.devices import table_limits
from station.settings import Settings

router = APIRouter(prefix="/api/procedures", tags=["procedures"])


def bench_table_limits(settings: Settings) -> TableLimits:
    """The table's limits for a viewer's question (:func:`~station.execution.devices.table_limits`).

    :raises HTTPException: 503 when the bench file became invalid since the service started,
        naming the key but not the server's path (the service's log has the whole line).
    """
    try:
        return table_limits(settings)
    except BenchConfigError as exc:
        raise HTTPException(
            status.HTTP_503_SERVICE_UNAVAILABLE,
            f"the bench file is invalid ({exc.key or 'the file'}): procedures cannot be checked "
            "against the table until it is fixed",
        ) from None


@router.get(
    "/{name}/preview", response_model=ProcedurePreviewOut, responses={404: {"description": "unknown"}}
)
def procedure_preview(
    name: str,
    settings: SettingsDep,
    _: ViewerDep,
    session: SessionDep,
    dwell_s: Annotated[float | None, Query(gt=0, le=86400)] = None,
    unit_serial: Annotated[str | None, Query(pattern=SERIAL_PATTERN)] = None,
    parameters: Annotated[
        str | None,
        Query(
            max_length=1000,
            description="the procedure's own parameters as a JSON object of numbers, as POST /api/runs "
            'takes them (e.g. {"repeats": 3, "settle_s": 2} of planned-static, as GET /api/plan gives '
            "them); default: the procedure's defaults",
            examples=['{"repeats": 3, "settle_s": 2.0}'],
        ),
    ] = None,
) -> ProcedurePreviewOut:
    """The procedure walked against the table's limits with the dwell a run started now would
    use (``dwell_s``, else the service's ``run_dwell_s``, else a provisional one that the run's
    noise window replaces) and its ``parameters``: every pose, the duration on the bench clock
    and, on a simulated bench, on the wall clock (bench seconds / ``sim_speed``). With
    ``unit_serial``, ``warnings`` says what the operator should know about that unit before
    starting (e.g. its model has no limits)."""
    dwell = dwell_s if dwell_s is not None else settings.run_dwell_s
    params = procedure_parameters(parameters)
    checked = check_procedure(name, bench_table_limits(settings), dwell_s=dwell, parameters=params)
    pv = preview_or_refuse(checked)
    warnings: list[str] = []
    if unit_serial is not None:
        with session.begin():
            warnings = unit_warnings(session, settings, unit_serial)
    speed = settings.sim_speed if settings.sim and settings.sim_speed > 0 else 1.0
    observable, not_observable = observability(name, dwell, tuple(sorted(params.items())))
    return ProcedurePreviewOut(
        procedure=name,
        duration_s=pv.duration_s,
        wall_duration_s=pv.duration_s / speed,
        n_poses=len(pv.poses_deg),
        poses_deg=[list(p) for p in pv.poses_deg],
        n_windows=len(pv.windows),
        observable=observable,
        not_observable=not_observable,
        dwell_s=dwell,
        dwell_source="given"
        if dwell_s is not None
        else "service setting"
        if dwell is not None
        else "provisional",
        assumptions=list(pv.assumptions),
        problems=list(pv.problems),
        warnings=warnings,
    )


MAX_PARAMETERS = 8
"""Most parameters a preview takes (as ``POST /api/runs``)."""


def procedure_parameters(text: str | None) -> dict[str, float]:
    """The ``parameters`` query: a JSON object of at most :data:`MAX_PARAMETERS` finite numbers
    by name. :raises HTTPException: 422 anything else."""
    if text is None:
        return {}
    out: dict[str, float] | None = None
    try:
        value = json.loads(text)
        numbers = isinstance(value, dict) and all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value.values()
        )
        if numbers and len(value) <= MAX_PARAMETERS:
            out = {str(k): float(v) for k, v in value.items()}  # OverflowError: an integer past float
    except (ValueError, OverflowError, RecursionError):
        out = None
    if out is None or not all(math.isfinite(v) for v in out.values()):
        raise HTTPException(
            status.HTTP_422_UNPROCESSABLE_CONTENT,
            f"parameters: expected a JSON object of at most {MAX_PARAMETERS} numbers by name",
        )
    return out


def preview_or_refuse(checked: Admitted | Refusal) -> Preview:
    """The preview of a checked procedure, also one the table limits refuse (the answer lists
    its problems). :raises HTTPException: 404 an unknown procedure, 422 a parameter or value
    it refuses."""
    if isinstance(checked, Admitted):
        return checked.preview
    if checked.kind is RefusalKind.UNKNOWN_PROCEDURE:
        raise HTTPException(status.HTTP_404_NOT_FOUND, checked.message)
    if checked.preview is None:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, checked.message)
    return checked.preview


OBSERVABILITY_RATE_HZ = 10.0
"""Time step of the observability check (Hz): the bound follows the noise density, not the rate."""


@functools.lru_cache(maxsize=64)
def observability(
    name: str, dwell_s: float | None, parameters: tuple[tuple[str, float], ...] = ()
) -> tuple[list[str], dict[str, str]]:
    """The model terms procedure ``name`` with ``dwell_s`` and ``parameters`` (name, value)
    determines, and why the others are not worth fitting
    (:func:`bench.procedures.observability.plan_observability`, computed once per procedure, dwell
    and parameters: seconds for a long moving-table procedure)."""
    proc = build_procedure(name, dwell_s=dwell_s, **dict(parameters))
    dwell = dwell_s if dwell_s is not None else provisional_dwell(proc)[0]
    _, why = plan_observability(proc, sample_rate_hz=OBSERVABILITY_RATE_HZ, dwell_s=dwell)
    terms = ("bias", "scale_matrix", *TERM_ORDER)
    return [t for t in terms if t not in why], {t: why[t] for t in terms if t in why}
