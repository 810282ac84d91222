"""``GET /api/plan``: the planned procedure for a unit's noise and target uncertainties."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, HTTPException, Query, status

from api.deps import SettingsDep, ViewerDep
from api.routes.procedures import bench_table_limits
from bench.planning.evaluation import Fit, Targets
from bench.planning.noise import G0_M_S2, UnitNoise
from bench.planning.report import plan_dict
from bench.planning.search import plan

router = APIRouter(prefix="/api", tags=["procedures"])

MAX_PLAN_MINUTES = 120.0


@router.get("/plan")
def plan_procedure(
    settings: SettingsDep,
    _: ViewerDep,
    white_ug_rt_hz: Annotated[float, Query(gt=0, le=1e6)],
    wander_ug: Annotated[float, Query(ge=0, le=1e6)] = 0.0,
    wander_tau_s: Annotated[float, Query(gt=0, le=1e6)] = 100.0,
    random_walk_ug_rt_s: Annotated[float, Query(ge=0, le=1e6)] = 0.0,
    bias_ug: Annotated[float | None, Query(gt=0, le=1e7)] = None,
    scale_ppm: Annotated[float | None, Query(gt=0, le=1e6)] = None,
    misalignment_urad: Annotated[float | None, Query(gt=0, le=1e6)] = None,
    settle_s: Annotated[float | None, Query(ge=0, le=60)] = None,
    max_minutes: Annotated[float, Query(gt=0, le=MAX_PLAN_MINUTES)] = 60.0,
    fit: Annotated[Literal["window", "every-sample", "best"], Query()] = "window",
) -> dict[str, Any]:
    """The shortest planned design on this bench's table limits whose fit meets the targets (U at
    k = 2: bias µg, scale ppm, misalignment µrad) for the unit's noise (µg/√Hz white, µg wander
    with its correlation time, µg/√s random walk), its predicted U, table time and the white-noise
    bound of any motion (docs/planning.md). The table's limits and, without ``settle_s``, its
    settling are the bench file's (``[table.limits]``, docs/bench-config.md). ``plan`` is ``null`` and
    ``problems`` says why when no design within ``max_minutes`` meets them; start the design with
    ``POST /api/runs`` (the plan's ``start``). ``fit``: ``window`` plans ``planned-static`` (the
    static window fit, the default), ``every-sample`` plans ``planned-tumble`` (the every-sample
    fit, moves included), ``best`` the shorter of the two, as ``calbench plan --fit`` does."""
    limits = bench_table_limits(settings)
    try:
        noise = UnitNoise.from_ug(white_ug_rt_hz, wander_ug, wander_tau_s, random_walk_ug_rt_s)
        targets = Targets(
            None if bias_ug is None else bias_ug * 1e-6 * G0_M_S2,
            None if scale_ppm is None else scale_ppm * 1e-6,
            None if misalignment_urad is None else misalignment_urad * 1e-6,
        )
        fits: tuple[Fit, ...] = ("window", "every-sample") if fit == "best" else (fit,)
        result = plan(
            noise, targets, limits=limits, settle_s=settle_s, max_duration_s=max_minutes * 60, fits=fits
        )
    except ValueError as exc:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(exc)) from None
    return plan_dict(result, noise.describe())
