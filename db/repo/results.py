"""Fitted models and diagnosis findings of runs."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import Finding, FitKind, FitModel, Run, Unit


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


def add_findings(session: Session, run_id: str, findings: Iterable[Mapping[str, Any]]) -> list[Finding]:
    """Store diagnosis findings, each a dict of the ``diagnose --json`` ``findings`` list.

    Keys: ``effect``, ``summary``, ``parameters``, ``sigma``, ``delta_bic`` and
    optionally ``residual_rms_after``.
    """
    rows = []
    for i, f in enumerate(findings):
        missing = [k for k in ("effect", "summary") if k not in f]
        if missing:
            raise ValueError(f"run {run_id} finding {i}: missing {', '.join(missing)}")
        numbers = {}
        for key in ("delta_bic", "residual_rms_after"):
            value = f.get(key)
            if value is not None and not math.isfinite(float(value)):
                raise ValueError(f"run {run_id} finding {i}: {key} = {value!r} is not finite")
            numbers[key] = None if value is None else float(value)
        rows.append(
            Finding(
                run_id=run_id,
                effect=str(f["effect"]),
                summary=str(f["summary"]),
                parameters=dict(f.get("parameters") or {}),
                sigma=dict(f.get("sigma") or {}),
                **numbers,
            )
        )
    session.add_all(rows)
    session.flush()
    return rows


def list_findings(session: Session, run_id: str) -> list[Finding]:
    """Findings of a run in the order they were stored."""
    return list(session.scalars(sa.select(Finding).where(Finding.run_id == run_id).order_by(Finding.id)))
