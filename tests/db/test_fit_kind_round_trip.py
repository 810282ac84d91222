"""Each kind of fit survives migration 0005 down and up, on SQLite and on PostgreSQL: a
database holding a static, an orientation-free and a moving fit, as the fits themselves wrote
them, comes back with the same ``fit_model`` rows; and a database made before the rows existed
(the fit only in ``params``) gets rows of the kind each fit chose, read from what its stored
object states (``bench.fit_kind.contract_kind``), never ``static`` for an orientation-free fit."""

from __future__ import annotations

from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.engine import Engine

from bench.fit_kind import FitKind
from db.engine import make_session_factory
from db.migrate import downgrade, upgrade
from db.models import FitModel, Run
from db.repo.results import add_fit
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from tests.db.old_schema import run_table
from tests.support.fits import DEFAULTS, calibration_result

FIT_AT_0004 = sa.table("fit_model", sa.column("run_id", sa.String))
RUN_AT_0004 = run_table()
MOVING_CONTRACT = {**DEFAULTS, "procedure": "rate-1axis", "method": "dynamic-batch", "extra": {}}


def _fits() -> dict[str, tuple[FitKind, dict[str, Any], Any, list[str]]]:
    """run id -> (the kind the fit chose, its contract object, covariance, parameter names)."""
    out: dict[str, tuple[FitKind, dict[str, Any], Any, list[str]]] = {}
    for kind in (FitKind.STATIC, FitKind.ORIENTATION_FREE):
        fit = calibration_result(kind, serial="SN-1")
        cov, names = fit.covariance_rows()
        out[f"R-{kind.value}"] = (kind, fit.to_contract(), np.array(cov), list(names))
    out["R-dynamic"] = (FitKind.MOVING, MOVING_CONTRACT, None, [])
    return out


def _stored(engine: Engine) -> list[tuple[str, str, dict[str, Any], list[Any], bytes | None]]:
    with make_session_factory(engine).begin() as s:
        return [
            (r.run_id, r.kind.value, r.contract, list(r.param_names),
             None if r.covariance is None else r.covariance.tobytes())
            for r in s.scalars(sa.select(FitModel).order_by(FitModel.id))
        ]  # fmt: skip


def _params(engine: Engine) -> dict[str, dict[str, Any]]:
    with make_session_factory(engine).begin() as s:
        return {run.id: dict(run.params) for run in s.scalars(sa.select(Run))}


def _fill_at_head(engine: Engine) -> dict[str, tuple[FitKind, dict[str, Any], Any, list[str]]]:
    upgrade(engine)
    fits = _fits()
    with make_session_factory(engine).begin() as s:
        bench = get_or_create_bench(s, "bench-a")
        unit = get_or_create_unit(s, "SN-1", channel_unit="V", bench_id=bench.id)
        for run_id, (kind, contract, cov, names) in fits.items():
            create_run(
                s, run_id, unit.id, str(contract["procedure"]), bench_id=bench.id, params={"n_poses": 12}
            )
            add_fit(s, run_id, kind.value, contract, covariance=cov, param_names=names)
    return fits


def test_every_fit_kind_round_trips_down_and_up(empty_engine: Engine) -> None:
    fits = _fill_at_head(empty_engine)
    rows, params = _stored(empty_engine), _params(empty_engine)
    assert [(r[0], r[1]) for r in rows] == [(i, f[0].value) for i, f in fits.items()]
    assert params == {i: {"n_poses": 12} for i in fits}
    downgrade(empty_engine, "0004")
    upgrade(empty_engine)
    assert _stored(empty_engine) == rows  # no row lost, changed or added
    assert _params(empty_engine) == params  # the fit went back to its row only


def test_a_fit_stored_without_a_row_gets_the_kind_it_chose(empty_engine: Engine) -> None:
    """The database of a release that kept the fit in ``params`` only: each run's new row has
    the kind the fit chose, whatever its procedure is called."""
    fits = _fill_at_head(empty_engine)
    downgrade(empty_engine, "0004")  # the fit back in params["calibration"]
    with empty_engine.begin() as conn:
        conn.execute(sa.delete(FIT_AT_0004))
        stored = dict(conn.execute(sa.select(RUN_AT_0004.c.id, RUN_AT_0004.c.params)).all())
    assert {i: p["calibration"] for i, p in stored.items()} == {i: f[1] for i, f in fits.items()}
    upgrade(empty_engine)
    kinds = {run_id: kind for run_id, kind, *_ in _stored(empty_engine)}
    assert kinds == {i: f[0].value for i, f in fits.items()}


def test_the_column_stores_the_names_of_migration_0001(empty_engine: Engine) -> None:
    """The ORM's kind is the one ``FitKind``, and it writes and reads the strings databases
    have held since migration 0001 created the column (``static``, ``scalar``, ``dynamic``)."""
    assert FitModel.__table__.c.kind.type.enum_class is FitKind
    _fill_at_head(empty_engine)
    with empty_engine.begin() as conn:
        raw = dict(conn.execute(sa.text("SELECT run_id, kind FROM fit_model")).all())
    assert raw == {"R-static": "static", "R-scalar": "scalar", "R-dynamic": "dynamic"}
    with make_session_factory(empty_engine).begin() as s:
        read = {r.run_id: r.kind for r in s.scalars(sa.select(FitModel))}
    assert read == {
        "R-static": FitKind.STATIC,
        "R-scalar": FitKind.ORIENTATION_FREE,
        "R-dynamic": FitKind.MOVING,
    }
