"""Fitted models and diagnosis findings of runs."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import Finding, FitKind, FitModel, Run, Unit

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
