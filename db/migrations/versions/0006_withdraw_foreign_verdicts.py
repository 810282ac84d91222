"""Runs: a PASS or FAIL stored against another model's limits is withdrawn, with an audit row.

A unit is judged only against its own model's limits (``bench.limits.choose_limits``); a
completed fit no limits judged has no outcome and ``run.conformity_note`` says why. Before
that rule a unit whose model the limits file lacks was judged against the default model's
limits (``limits_model``), and its run kept that PASS or FAIL. This revision finds such runs
from what they stored and withdraws the verdict.

A run is a candidate when it is ``completed``, its outcome is ``PASS`` or ``FAIL``, it stored
limit checks, and its unit's registration names a model X (a unit naming no model is judged
by the default model under the rule too). The model Y whose limits judged it is read from:

1. the run's newest certificate: its conformity section's ``specification`` ("limits of unit
   model Y");
2. else the models of the limits file (``CALBENCH_LIMITS_FILE``, else the one calbench ships)
   whose every limit has the stored check's bounds (same name, ``low`` and ``high`` to a
   relative 1e-9); several models with identical limits are all named;
3. else none is known.

The verdict is withdrawn when Y is known and is not X (X not among the matching models), or
when no Y is known and the limits file has no model X (the old rule then judged X by another
model's limits). A run whose stored bounds match no model while X is in the file (its limits
edited since) keeps its verdict.

A withdrawn run gets outcome ``NULL``, the ``conformity_note`` "no conformity statement: the
unit's model X has no limits; the PASS recorded on <date> against model Y's limits was
withdrawn by migration 0006", and a ``run_audit`` row (action ``withdraw``, actor ``migration
0006``, the UTC time of the migration) whose detail starts with the withdrawn outcome and
names the certificate that stated it. An issued certificate is a signed document
(``certificate.sha256``) and is not rewritten; the certificate API shows the withdrawal
beside it. The stored limit checks stay as the record of what was computed.

``run_audit.action`` gains ``withdraw``. The downgrade puts each withdrawn outcome back from
its audit row, clears the note, deletes those rows and narrows the action list again.

Revision ID: 0006
Revises: 0005
"""

from __future__ import annotations

import datetime as dt
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import sqlalchemy as sa
from alembic import op

import db.types
from bench.limits import UnitLimits, load_limits

revision: str = "0006"
down_revision: str | None = "0005"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

ACTOR = "migration 0006"
OLD_ACTIONS = ("start", "pause", "continue", "abort", "resume", "state")
NEW_ACTIONS = (*OLD_ACTIONS, "withdraw")
"""``run_audit.action`` before and after this revision (frozen here)."""
VERDICTS = ("PASS", "FAIL")
SPECIFICATION = "limits of unit model "
"""How a certificate's conformity section names the limits' model (``specification``)."""
REL_TOL = 1e-9

_run = sa.table(
    "run",
    sa.column("id", sa.String),
    sa.column("unit_id", sa.Integer),
    sa.column("state", sa.String),
    sa.column("outcome", sa.String),
    sa.column("finished_at", db.types.UtcDateTime),
    sa.column("started_at", db.types.UtcDateTime),
    sa.column("limit_checks", sa.JSON),
    sa.column("conformity_note", sa.Text),
)
_unit = sa.table("unit", sa.column("id", sa.Integer), sa.column("model", sa.String))
_cert = sa.table(
    "certificate",
    sa.column("id", sa.Integer),
    sa.column("run_id", sa.String),
    sa.column("number", sa.String),
    sa.column("issued_at", db.types.UtcDateTime),
    sa.column("content", sa.JSON),
)
_audit = sa.table(
    "run_audit",
    sa.column("id", sa.Integer),
    sa.column("run_id", sa.String),
    sa.column("at", db.types.UtcDateTime),
    sa.column("actor", sa.String),
    sa.column("action", sa.String),
    sa.column("state", sa.String),
    sa.column("detail", sa.Text),
    sa.column("window_index", sa.Integer),
)


def _action_type(actions: tuple[str, ...]) -> sa.Enum:
    return sa.Enum(*actions, name="audit_action", native_enum=False, create_constraint=True, length=16)


def _set_actions(old: tuple[str, ...], new: tuple[str, ...]) -> None:
    if op.get_bind().dialect.name == "sqlite":  # run_audit has no child rows: a batch copy is safe
        with op.batch_alter_table("run_audit") as batch:
            batch.alter_column("action", existing_type=_action_type(old), type_=_action_type(new))
        return
    op.drop_constraint(op.f("ck_run_audit__audit_action"), "run_audit", type_="check")
    listed = ", ".join(f"'{a}'" for a in new)
    op.create_check_constraint(
        op.f("ck_run_audit__audit_action"), "run_audit", sa.text(f"action IN ({listed})")
    )


def _same(a: object, b: float | None) -> bool:
    if b is None or a is None:
        return a is None and b is None
    return isinstance(a, int | float) and math.isclose(float(a), b, rel_tol=REL_TOL, abs_tol=0.0)


def _reproduces(limits: UnitLimits, checks: Sequence[Any]) -> bool:
    """Whether every stored check has the bounds of ``limits``' limit of its name."""
    by_name = {lim.name: lim for lim in limits.limits}
    if len(checks) != len(by_name):
        return False
    for c in checks:
        lim = by_name.get(str(c.get("name"))) if isinstance(c, Mapping) else None
        if lim is None or not (_same(c.get("low"), lim.low) and _same(c.get("high"), lim.high)):
            return False
    return True


def _certified_model(content: object) -> str | None:
    """The limits' model a certificate's conformity section names, ``None`` if it names none."""
    conformity = content.get("conformity") if isinstance(content, Mapping) else None
    spec = conformity.get("specification") if isinstance(conformity, Mapping) else None
    if isinstance(spec, str) and spec.startswith(SPECIFICATION):
        name = spec[len(SPECIFICATION) :].strip()
        return name if name and name != "not stated" else None
    return None


def _judged_by(checks: Sequence[Any], cert: Any | None, table: Mapping[str, UnitLimits]) -> tuple[str, ...]:
    """The model(s) whose limits judged a run (see the module text), ``()`` when not known."""
    if cert is not None and (named := _certified_model(cert.content)):
        return (named,)
    return tuple(sorted(name for name, limits in table.items() if _reproduces(limits, checks)))


def _day(run: Any) -> str:
    at = run.finished_at or run.started_at
    return at.astimezone(dt.UTC).date().isoformat() if at is not None else "an unrecorded date"


def upgrade() -> None:
    _set_actions(OLD_ACTIONS, NEW_ACTIONS)
    conn = op.get_bind()
    rows = conn.execute(
        sa.select(_run, _unit.c.model)
        .join(_unit, _unit.c.id == _run.c.unit_id)
        .where(_run.c.state == "completed", _run.c.outcome.in_(VERDICTS))
        .order_by(_run.c.id)
    ).all()
    if not rows:
        return
    table = load_limits(os.environ.get("CALBENCH_LIMITS_FILE") or None)
    now = db.types.utc_now()
    for run in rows:
        model = (run.model or "").strip()
        checks = run.limit_checks if isinstance(run.limit_checks, list) else []
        if not model or not checks:
            continue
        cert = conn.execute(
            sa.select(_cert).where(_cert.c.run_id == run.id).order_by(_cert.c.id.desc()).limit(1)
        ).first()
        judged = _judged_by(checks, cert, table)
        if model in judged or (not judged and model in table):
            continue
        against = (
            f"model {' or '.join(judged)}'s limits" if judged else f"limits of a model other than {model}"
        )
        note = (
            f"no conformity statement: the unit's model {model} has no limits; the {run.outcome} "
            f"recorded on {_day(run)} against {against} was withdrawn by migration 0006"
        )
        issued = (
            f"; certificate {cert.number} (issued {cert.issued_at.astimezone(dt.UTC).date().isoformat()}) "
            "states it and is kept unchanged as issued"
            if cert is not None
            else ""
        )
        conn.execute(sa.update(_run).where(_run.c.id == run.id).values(outcome=None, conformity_note=note))
        conn.execute(
            sa.insert(_audit).values(
                run_id=run.id,
                at=now,
                actor=ACTOR,
                action="withdraw",
                state=None,
                detail=f"{run.outcome} withdrawn: judged against {against}, "
                f"the unit's model is {model}{issued}",
                window_index=None,
            )
        )


def downgrade() -> None:
    conn = op.get_bind()
    rows = conn.execute(
        sa.select(_audit.c.run_id, _audit.c.detail).where(
            _audit.c.action == "withdraw", _audit.c.actor == ACTOR
        )
    ).all()
    for run_id, detail in rows:
        outcome = str(detail).split(" ", 1)[0]
        if outcome in VERDICTS:
            conn.execute(
                sa.update(_run).where(_run.c.id == run_id).values(outcome=outcome, conformity_note=None)
            )
    conn.execute(sa.delete(_audit).where(_audit.c.action == "withdraw"))
    _set_actions(NEW_ACTIONS, OLD_ACTIONS)
