"""Drift checks in the database: which units are due and on which bench, which checks wait or
run, and storing a finished check's comparison
(:func:`bench.uncertainty.drift.compare`) with the unit's latest certificate."""

from __future__ import annotations

from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from bench.records import RunRecord
from bench.uncertainty.drift import compare
from db.models import ACTIVE_STATES, Bench, Certificate, DriftCheck, Run, RunState, Unit
from db.repo.certificates import latest_certificate
from db.repo.drift import add_drift_check
from db.repo.units import get_unit_by_serial
from station.certificates.statements import NOT_STATED
from station.drift.plan import DueUnit
from station.settings import Settings


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


def unit_bench(s: Session, unit: Unit) -> str | None:
    """The name of the unit's bench: the one it was last run on, else its latest certificate's
    (:func:`certificate_bench`); ``None`` when neither is known."""
    if unit.bench_id is not None:
        bench = s.get(Bench, unit.bench_id)
        if bench is not None:
            return bench.name
    cert = latest_certificate(s, unit.id)
    return certificate_bench(s, cert) if cert is not None else None


def units_due(s: Session) -> list[DueUnit]:
    """Every unit that has a certificate, by serial, with its bench (:func:`unit_bench`), on
    whichever bench of the lab it is."""
    stmt = sa.select(Unit).where(sa.exists().where(Certificate.unit_id == Unit.id)).order_by(Unit.serial)
    return [DueUnit(unit.serial, unit_bench(s, unit)) for unit in s.scalars(stmt)]


def drift_checks_in_queue(s: Session) -> tuple[list[str], list[str]]:
    """Serials of the units whose drift check waits in a bench's queue, and of those whose check
    holds its bench (running, paused or suspended), each by serial."""
    rows = s.execute(
        sa.select(Unit.serial, Run.state)
        .join(Unit, Run.unit_id == Unit.id)
        .where(Run.state.in_(list(ACTIVE_STATES)), Run.kind == "drift_check")
        .order_by(Unit.serial)
    ).all()
    checks = [(serial, state) for serial, state in rows]
    waiting = [serial for serial, state in checks if state is RunState.QUEUED]
    holding = [serial for serial, state in checks if state is not RunState.QUEUED]
    return waiting, holding
