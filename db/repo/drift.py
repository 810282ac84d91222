"""Drift checks: a unit re-measured and compared with its reference certificate."""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import DriftCheck
from db.types import utc_now


def add_drift_check(
    session: Session,
    unit_id: int,
    result: Mapping[str, Any],
    flagged: bool,
    *,
    run_id: str | None = None,
    reference_certificate_id: int | None = None,
    checked_at: dt.datetime | None = None,
) -> DriftCheck:
    """Store a drift check; ``flagged`` when the unit moved beyond its uncertainties."""
    check = DriftCheck(
        unit_id=unit_id,
        run_id=run_id,
        reference_certificate_id=reference_certificate_id,
        result=dict(result),
        flagged=bool(flagged),
        checked_at=checked_at or utc_now(),
    )
    session.add(check)
    session.flush()
    return check


def list_drift_checks(session: Session, unit_id: int, *, flagged_only: bool = False) -> list[DriftCheck]:
    """The unit's drift checks, oldest first."""
    stmt = sa.select(DriftCheck).where(DriftCheck.unit_id == unit_id)
    if flagged_only:
        stmt = stmt.where(DriftCheck.flagged.is_(True))
    return list(session.scalars(stmt.order_by(DriftCheck.checked_at, DriftCheck.id)))
