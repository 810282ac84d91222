"""Drift checks in the database: which units are due, and storing a finished check's comparison
(:func:`bench.uncertainty.drift.compare`) with the unit's latest certificate."""

from __future__ import annotations

from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from api.certificates.statements import NOT_STATED
from api.settings import Settings
from bench.records import RunRecord
from bench.uncertainty.drift import compare
from db.models import Bench, Certificate, DriftCheck, Run, Unit
from db.repo.certificates import latest_certificate
from db.repo.drift import add_drift_check
from db.repo.units import get_bench_by_name, get_unit_by_serial


def certificate_bench(s: Session, cert: Certificate) -> str | None:
    """The name of the bench a certificate's run was on: the content's ``bench``, else the run's
    bench row; ``None`` when neither states it."""
    name = cert.content.get("bench")
    if isinstance(name, str) and name.strip() and name != NOT_STATED:
        return name
    run = s.get(Run, cert.run_id)
    bench = s.get(Bench, run.bench_id) if run is not None and run.bench_id is not None else None
    return bench.name if bench is not None else None


def record_drift_check(s: Session, settings: Settings, serial: str, record: RunRecord) -> DriftCheck:
    """Store the drift check of ``serial`` from a finished check run (flagged or not).

    :raises LookupError: the unit is unknown.
    """
    unit = get_unit_by_serial(s, serial)
    if unit is None:
        raise LookupError(f"unit {serial} not found")
    cert = latest_certificate(s, unit.id)
    result: dict[str, Any] = {"procedure": record.start.procedure, "outcome": None, "status": "no_result"}
    flagged = False
    if record.outcome is not None:
        result["outcome"] = record.outcome.value
    if cert is None:
        result["error"] = "the unit has no certificate to compare with"
    elif record.calibration is None:
        result["error"] = record.error or "the check run produced no fit"
    else:
        check = record.calibration.fitted_model()
        k_diag = np.abs(np.diag(np.asarray(check.K, dtype=float)))
        rep = k_diag * float(getattr(settings, "drift_bias_repeatability_m_s2", 0.0))
        cert_bench = certificate_bench(s, cert)
        same = cert_bench is not None and cert_bench == record.start.bench_name
        result = {
            **result,
            **compare(cert.content, check, settings.drift_k, bias_repeatability=rep, same_bench=same),
        }
        result["status"] = "compared"
        result["reference_number"] = cert.number
        result["reference_bench"], result["check_bench"] = cert_bench, record.start.bench_name
        flagged = bool(result["flagged"])
    return add_drift_check(
        s,
        unit.id,
        result,
        flagged,
        run_id=record.run_id,
        reference_certificate_id=cert.id if cert is not None else None,
    )


def units_due(s: Session, bench_name: str) -> list[str]:
    """Serials of this bench's units that have a certificate."""
    bench = get_bench_by_name(s, bench_name)
    if bench is None:
        return []
    stmt = (
        sa.select(Unit.serial)
        .where(Unit.bench_id == bench.id, sa.exists().where(Certificate.unit_id == Unit.id))
        .order_by(Unit.serial)
    )
    return list(s.scalars(stmt))
