"""Migration 0006 on a database made at revision 0005: a PASS or FAIL a run stored against
another model's limits (a unit of a model the limits file lacks, judged by the default model)
is withdrawn with a note and an audit row, on SQLite and on PostgreSQL; a verdict against the
unit's own model's limits, a run without limit checks and a unit naming no model keep theirs;
the downgrade gives every outcome back."""

from __future__ import annotations

import dataclasses
import datetime as dt
from typing import Any

import pytest
import sqlalchemy as sa
from sqlalchemy.engine import Engine

from bench.limits import load_limits
from db.engine import make_session_factory
from db.migrate import current_revision, downgrade, upgrade
from db.types import UtcDateTime
from tests.db.old_schema import SETUP, at_revision, row_counts, run_table

# the tables as revision 0005 has them (not the models: they follow the newest revision)
RUN = run_table(
    sa.column("outcome", sa.String),
    sa.column("kind", sa.String),
    sa.column("finished_at", UtcDateTime()),
    sa.column("conformity_note", sa.Text),
)
UNIT = sa.table(
    "unit", sa.column("id", sa.Integer), sa.column("serial", sa.String), sa.column("model", sa.String)
)
CERT = sa.table(
    "certificate",
    sa.column("run_id", sa.String),
    sa.column("unit_id", sa.Integer),
    sa.column("year", sa.Integer),
    sa.column("serial", sa.Integer),
    sa.column("number", sa.String),
    sa.column("content", sa.JSON),
    sa.column("sha256", sa.String),
    sa.column("issued_at", UtcDateTime()),
)
OWN, FOREIGN = "ADXL325", "ADXL335"  # the shipped limits file has the first, not the second
FINISHED = dt.datetime(2026, 3, 4, 22, 30, tzinfo=dt.UTC)


def _checks(fail: bool = False) -> list[dict[str, Any]]:
    """Checks as the bench stored them against ``OWN``'s limits (value at the middle of each)."""
    out = []
    for i, lim in enumerate(load_limits()[OWN].limits):
        assert lim.low is not None and lim.high is not None
        mid = 0.5 * (lim.low + lim.high)
        value = lim.high * 2 + 1 if fail and i == 0 else mid
        out.append(dataclasses.asdict(lim.check(value)))
    return out


@dataclasses.dataclass(frozen=True)
class Case:
    unit_id: int
    outcome: str | None
    checks: list[dict[str, Any]]
    state: str = "completed"
    certified: bool = False
    withdrawn: str | None = None
    """the note the upgrade writes, worked out here by hand; ``None``: the run is unchanged"""


CASES = {
    "R-OWN": Case(1, "PASS", _checks()),  # ADXL325 judged by its own limits
    "R-OWN-FAIL": Case(1, "FAIL", _checks(fail=True)),
    "R-PASS": Case(
        2,
        "PASS",
        _checks(),
        certified=True,
        withdrawn="no conformity statement: the unit's model ADXL335 has no limits; the PASS recorded on "
        "2026-03-04 against model ADXL325's limits was withdrawn by migration 0006",
    ),
    "R-FAIL": Case(
        2,
        "FAIL",
        _checks(fail=True),
        withdrawn="no conformity statement: the unit's model ADXL335 has no limits; the FAIL recorded on "
        "2026-03-04 against model ADXL325's limits was withdrawn by migration 0006",
    ),
    "R-NOCHECKS": Case(2, "PASS", []),  # nothing stored to tell the limits by: kept
    "R-ERROR": Case(2, "ERROR", [], state="error"),
    "R-NOMODEL": Case(3, "PASS", _checks()),  # the default model still judges a unit naming none
}


def _fill_at_0005(engine: Engine) -> None:
    at_revision(engine, "0005")
    with engine.begin() as conn:
        conn.execute(sa.update(UNIT).where(UNIT.c.id == 1).values(model=OWN))
        conn.execute(sa.insert(UNIT).values(id=2, serial="SN-2", model=FOREIGN))
        conn.execute(sa.insert(UNIT).values(id=3, serial="SN-3", model=None))
        for run_id, case in CASES.items():
            conn.execute(
                sa.insert(RUN).values(
                    id=run_id,
                    unit_id=case.unit_id,
                    bench_id=1,
                    procedure="static-12",
                    state=case.state,
                    outcome=case.outcome,
                    progress=1.0,
                    params={"run_id": run_id, **SETUP},
                    resume_count=0,
                    limit_checks=case.checks,
                    kind="calibration",
                    finished_at=FINISHED,
                    conformity_note=None,
                )
            )
            if case.certified:
                content = {
                    "conformity": {
                        "requested": True,
                        "outcome": case.outcome,
                        "specification": f"limits of unit model {OWN}",
                    }
                }
                conn.execute(
                    sa.insert(CERT).values(
                        run_id=run_id,
                        unit_id=case.unit_id,
                        year=2026,
                        serial=1,
                        number="CB-2026-00001",
                        content=content,
                        sha256="cd" * 32,
                        issued_at=FINISHED,
                    )
                )


def _check_upgrade(engine: Engine, before: dt.datetime) -> None:
    from api.routes.views import certificate_out, run_out
    from db.models import AuditAction, Certificate, Run, RunAudit
    from db.repo.results import results_of_runs

    with make_session_factory(engine).begin() as s:
        for run_id, case in CASES.items():
            run = s.get(Run, run_id)
            assert run is not None
            audit = s.scalars(sa.select(RunAudit).where(RunAudit.run_id == run_id)).all()
            assert run.limit_checks == case.checks, run_id  # the record of what was computed stays
            if case.withdrawn is None:
                assert (run.outcome, run.conformity_note, audit) == (case.outcome, None, []), run_id
                continue
            assert run.outcome is None and run.conformity_note == case.withdrawn, run_id
            assert len(audit) == 1, run_id
            row = audit[0]
            assert (row.actor, row.action, row.state) == ("migration 0006", AuditAction.WITHDRAW, None)
            assert before <= row.at <= dt.datetime.now(dt.UTC) and row.at.utcoffset() == dt.timedelta(0)
            assert row.detail.startswith(f"{case.outcome} withdrawn: judged against model ADXL325's limits")
            assert ("certificate CB-2026-00001" in row.detail) == case.certified, run_id
            out = run_out(run, "SN-2", results=results_of_runs(s, [run_id])[run_id])
            assert (out.outcome, out.conformity_note) == (None, case.withdrawn)
        cert = s.scalars(sa.select(Certificate)).one()
        assert cert.content["conformity"]["outcome"] == "PASS"  # the issued document is not rewritten
        shown = certificate_out(cert, "SN-2", s.get(Run, cert.run_id))
        assert shown.conformity_withdrawn == CASES["R-PASS"].withdrawn
        assert certificate_out(cert, "SN-2", None).conformity_withdrawn is None


def test_0006_withdraws_verdicts_against_other_models_limits(empty_engine: Engine) -> None:
    """On SQLite and on PostgreSQL (``tests.pg.empty_engine``)."""
    _fill_at_0005(empty_engine)
    tables = ("run", "run_window", "certificate", "fit_model")
    counts = row_counts(empty_engine, tables)
    before = dt.datetime.now(dt.UTC).replace(microsecond=0)
    upgrade(empty_engine, "0006")
    assert current_revision(empty_engine) == "0006"
    assert row_counts(empty_engine, tables) == counts
    assert row_counts(empty_engine, ("run_audit",)) == {"run_audit": 2}
    _check_upgrade(empty_engine, before)

    downgrade(empty_engine, "0005")
    assert current_revision(empty_engine) == "0005"
    assert row_counts(empty_engine, (*tables, "run_audit")) == {**counts, "run_audit": 0}
    with empty_engine.connect() as conn:
        stored = {r.id: (r.outcome, r.conformity_note) for r in conn.execute(sa.select(RUN))}
    assert stored == {run_id: (case.outcome, None) for run_id, case in CASES.items()}

    audit = sa.table("run_audit", *(sa.column(c) for c in ("run_id", "at", "actor", "action", "detail")))
    with pytest.raises(sa.exc.IntegrityError), empty_engine.begin() as conn:  # 0005 knows no withdraw
        conn.execute(
            sa.insert(audit).values(run_id="R-OWN", at=FINISHED, actor="x", action="withdraw", detail="")
        )

    upgrade(empty_engine)  # and up again: the same withdrawals
    _check_upgrade(empty_engine, before)
