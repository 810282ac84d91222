"""Fitted models, diagnoses and diagnosis findings of runs.

A run's fit has one home: its ``fit_model`` row (the newest, should there be several), whose
``contract`` is the ``calbench calibrate --json`` object every reader shows and parses.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Collection, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa
from sqlalchemy.orm import Session

from bench.fit_kind import FitKind
from bench.records import GapRecord
from db.models import Finding, FitModel, Run, Unit
from db.notify import notify_run
from db.repo.gaps import gaps_of_runs

if TYPE_CHECKING:  # the type only: the diagnosis package (scipy) stays out of the database layer
    from bench.diagnosis.stored import StoredFinding


def add_fit(
    session: Session,
    run_id: str,
    kind: FitKind | str,
    contract: Mapping[str, Any],
    *,
    covariance: npt.ArrayLike | None = None,
    param_names: Sequence[str] = (),
) -> FitModel:
    """Store a fitted model of ``run_id``.

    :param contract: the ``calibrate --json`` object.
    :param covariance: (n, n) symmetric, finite parameter covariance, or ``None``.
    :param param_names: the n parameter names in covariance order (required with covariance).
    :raises ValueError: covariance not square, not finite, not symmetric, or names mismatched.
    """
    kind = FitKind(kind)
    cov = None
    if covariance is not None:
        cov = np.asarray(covariance, dtype=np.float64)
        where = f"run {run_id} {kind.value} fit covariance"
        if cov.ndim != 2 or cov.shape[0] != cov.shape[1]:
            raise ValueError(f"{where}: expected a square (n, n) array, got shape {cov.shape}")
        if not np.all(np.isfinite(cov)):
            raise ValueError(f"{where}: contains non-finite values")
        if not np.allclose(cov, cov.T, rtol=1e-9, atol=0.0):
            raise ValueError(f"{where}: not symmetric")
        if len(param_names) != cov.shape[0]:
            raise ValueError(
                f"{where}: {len(param_names)} parameter names for a {cov.shape[0]}x{cov.shape[0]} matrix"
            )
    fit = FitModel(
        run_id=run_id, kind=kind, contract=dict(contract), covariance=cov, param_names=list(param_names)
    )
    session.add(fit)
    session.flush()
    return fit


def list_fits(session: Session, run_id: str) -> list[FitModel]:
    """Fits of a run, oldest first."""
    return list(session.scalars(sa.select(FitModel).where(FitModel.run_id == run_id).order_by(FitModel.id)))


def fit_of_run(session: Session, run_id: str) -> FitModel | None:
    """The run's fit (its newest ``fit_model`` row), ``None``: the run has none."""
    stmt = sa.select(FitModel).where(FitModel.run_id == run_id).order_by(FitModel.id.desc()).limit(1)
    return session.scalars(stmt).one_or_none()


def fit_contract(session: Session, run_id: str) -> dict[str, Any] | None:
    """The ``calibrate --json`` object of the run's fit, ``None``: the run has none."""
    fit = fit_of_run(session, run_id)
    return fit.contract if fit is not None else None


def fit_contracts(session: Session, run_ids: Collection[str]) -> dict[str, dict[str, Any]]:
    """The ``calibrate --json`` object of each run's fit, by run id (runs without one left out),
    in one query."""
    if not run_ids:
        return {}
    newest = (
        sa.select(sa.func.max(FitModel.id))
        .where(FitModel.run_id.in_(list(run_ids)))
        .group_by(FitModel.run_id)
    )
    rows = session.execute(sa.select(FitModel.run_id, FitModel.contract).where(FitModel.id.in_(newest)))
    return {str(run_id): contract for run_id, contract in rows}


@dataclasses.dataclass(frozen=True)
class RunResults:
    """What a run's views show from beyond its ``run`` row.

    :param fit: the ``calibrate --json`` object of the run's fit, ``None``: none.
    :param gaps: the run's sample gaps, in order.
    """

    fit: dict[str, Any] | None = None
    gaps: tuple[GapRecord, ...] = ()


def results_of_runs(session: Session, run_ids: Collection[str]) -> dict[str, RunResults]:
    """:class:`RunResults` of each run, by run id (every id present), in two queries."""
    fits, gaps = fit_contracts(session, run_ids), gaps_of_runs(session, run_ids)
    return {i: RunResults(fits.get(i), tuple(gaps.get(i, ()))) for i in run_ids}


def set_diagnosis(
    session: Session, run_id: str, contract: Mapping[str, Any] | None, error: str | None
) -> None:
    """Store the run's diagnosis (the ``diagnose --json`` object) or why there is none (``error``
    with ``contract`` ``None``); the run's listeners are told at commit.

    :raises LookupError: no such run.
    """
    values = {"diagnosis": dict(contract) if contract is not None else None, "diagnosis_error": error}
    if contract is None:
        values.pop("diagnosis")  # a note on a later failure keeps a diagnosis stored before
    result = session.execute(sa.update(Run).where(Run.id == run_id).values(**values))
    if getattr(result, "rowcount", 0) != 1:
        raise LookupError(f"run {run_id} not found")
    notify_run(session, run_id)


def latest_fit_for_unit(
    session: Session, unit_serial: str, kind: FitKind | str | None = None
) -> FitModel | None:
    """The newest fit of any run of the unit (optionally of one ``kind``), or ``None``."""
    stmt = (
        sa.select(FitModel)
        .join(Run, FitModel.run_id == Run.id)
        .join(Unit, Run.unit_id == Unit.id)
        .where(Unit.serial == unit_serial)
        .order_by(FitModel.id.desc())
        .limit(1)
    )
    if kind is not None:
        stmt = stmt.where(FitModel.kind == FitKind(kind))
    return session.scalars(stmt).one_or_none()


def add_findings(session: Session, run_id: str, findings: Iterable[StoredFinding]) -> list[Finding]:
    """Store diagnosis findings (``bench.diagnosis.stored.StoredFinding``, parsed or fresh).

    :raises ValueError: a finding's ``delta_bic`` or ``residual_rms_after`` is not finite (named).
    """
    rows = []
    for i, f in enumerate(findings):
        numbers = {"delta_bic": f.delta_bic, "residual_rms_after": f.residual_rms_after}
        for key, value in numbers.items():
            if value is not None and not math.isfinite(value):
                raise ValueError(f"run {run_id} finding {i}: {key} = {value!r} is not finite")
        rows.append(
            Finding(
                run_id=run_id,
                effect=f.effect,
                summary=f.summary,
                parameters=dict(f.parameters),
                sigma=dict(f.sigma),
                **numbers,
            )
        )
    session.add_all(rows)
    session.flush()
    return rows


def list_findings(session: Session, run_id: str) -> list[Finding]:
    """Findings of a run in the order they were stored."""
    return list(session.scalars(sa.select(Finding).where(Finding.run_id == run_id).order_by(Finding.id)))
