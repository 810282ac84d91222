"""Runs: control requests and service bookkeeping in typed columns (out of ``params``), the
audit trail of every action on a run, and the operator a token names.

``params`` keeps the procedure's parameters (and the analysis results until they get their
own rows). The keys moved, with their columns:

=========================  =======================================
``params`` key (≤ 0003)    ``run`` column (0004)
=========================  =======================================
``service_kind``           ``kind``
``request.dwell_s``        ``requested_dwell_s``
``drift_night``            ``drift_night``
``service_sim_age_days``   ``sim_age_days``
``abort_requested``        ``abort_request`` (the reason)
``control.seq/.action``    ``control_seq``, ``control_action``
``resume_requested``       ``resume_requested``
``finishing_since``        ``finishing_since`` (ISO 8601 text to a UTC time)
``auto_resume``            ``auto_resume``
``live``                   ``live_progress``
``service_finished``       ``final_event``
=========================  =======================================

A key of ``request`` other than ``dwell_s`` stays in ``params["request"]``. The downgrade
puts every value back where it was. The ``run`` columns are added and dropped with ``ALTER
TABLE`` on SQLite too: a batch copy of ``run`` drops the old table, which with foreign keys on
deletes every row that refers to a run (fits, findings, windows, chunks).

Revision ID: 0004
Revises: 0003
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from typing import Any

import sqlalchemy as sa
from alembic import op

import db.types

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

RUN_STATES = (
    "queued",
    "running",
    "paused",
    "suspended",
    "interrupted",
    "completed",
    "failed",
    "error",
    "aborted",
)
"""The stored run states as of this revision (frozen here: a migration does not follow the code)."""


def _columns() -> tuple[sa.Column[Any], ...]:
    """The new ``run`` columns (fresh objects: a column belongs to one table)."""
    return (
        sa.Column("kind", sa.String(16), nullable=True),
        sa.Column("requested_dwell_s", sa.Double(), nullable=True),
        sa.Column("drift_night", sa.String(40), nullable=True),
        sa.Column("sim_age_days", sa.Double(), nullable=True),
        sa.Column("abort_request", sa.Text(), nullable=True),
        sa.Column("control_seq", sa.Integer(), server_default="0", nullable=False),
        sa.Column("control_action", sa.String(16), nullable=True),
        sa.Column("resume_requested", sa.Boolean(), server_default=sa.false(), nullable=False),
        sa.Column("finishing_since", db.types.UtcDateTime(), nullable=True),
        sa.Column("auto_resume", sa.JSON(), nullable=True),
        sa.Column("live_progress", sa.JSON(), nullable=True),
        sa.Column("final_event", sa.JSON(), nullable=True),
    )


_run = sa.table(
    "run",
    sa.column("id", sa.String),
    sa.column("params", sa.JSON),
    *(sa.column(c.name, c.type) for c in _columns()),
)


def _utc(text: Any) -> dt.datetime | None:
    """An ISO 8601 time as a UTC ``datetime`` (a naive one taken as UTC), ``None`` if it is not one."""
    if not isinstance(text, str):
        return None
    try:
        at = dt.datetime.fromisoformat(text)
    except ValueError:
        return None
    return at.replace(tzinfo=dt.UTC) if at.tzinfo is None else at.astimezone(dt.UTC)


def _moved(params: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the columns' values, what stays in params) of one run's ``params``."""
    rest = dict(params)
    values: dict[str, Any] = {}
    kind = rest.pop("service_kind", None)
    values["kind"] = str(kind) if kind is not None else None
    request = rest.pop("request", None)
    if isinstance(request, dict):
        request = dict(request)
        dwell = request.pop("dwell_s", None)
        values["requested_dwell_s"] = float(dwell) if isinstance(dwell, int | float) else None
        if dwell is not None and not isinstance(dwell, int | float):
            request["dwell_s"] = dwell  # not a number: kept as it was
        if request:
            rest["request"] = request
    elif request is not None:
        rest["request"] = request
    night = rest.pop("drift_night", None)
    values["drift_night"] = str(night) if night is not None else None
    age = rest.pop("service_sim_age_days", None)
    values["sim_age_days"] = float(age) if isinstance(age, int | float) else None
    if age is not None and not isinstance(age, int | float):
        rest["service_sim_age_days"] = age
    abort = rest.pop("abort_requested", None)
    values["abort_request"] = str(abort) if abort else None
    control = rest.pop("control", None)
    if isinstance(control, dict):
        values["control_seq"] = int(control.get("seq", 0))
        action = control.get("action")
        values["control_action"] = str(action) if action is not None else None
    else:
        values["control_seq"], values["control_action"] = 0, None
        if control is not None:
            rest["control"] = control
    values["resume_requested"] = bool(rest.pop("resume_requested", False))
    since = rest.pop("finishing_since", None)
    values["finishing_since"] = _utc(since)
    if since is not None and values["finishing_since"] is None:
        rest["finishing_since"] = since  # not a time: kept as it was
    auto = rest.pop("auto_resume", None)
    values["auto_resume"] = auto if isinstance(auto, dict) else None
    if auto is not None and not isinstance(auto, dict):
        rest["auto_resume"] = auto
    live = rest.pop("live", None)
    values["live_progress"] = live if isinstance(live, dict) else None
    if live is not None and not isinstance(live, dict):
        rest["live"] = live
    finished = rest.pop("service_finished", None)
    values["final_event"] = finished if isinstance(finished, dict) else None
    if finished is not None and not isinstance(finished, dict):
        rest["service_finished"] = finished
    return values, rest


def _restored(row: Any) -> dict[str, Any]:
    """``params`` as revision 0003 kept it, from a row of this revision."""
    params = dict(row.params or {})
    if row.kind is not None:
        params["service_kind"] = row.kind
    if row.requested_dwell_s is not None or row.kind is not None:
        params["request"] = {**(params.get("request") or {}), "dwell_s": row.requested_dwell_s}
    if row.drift_night is not None:
        params["drift_night"] = row.drift_night
    if row.sim_age_days is not None:
        params["service_sim_age_days"] = row.sim_age_days
    if row.abort_request is not None:
        params["abort_requested"] = row.abort_request
    if row.control_seq:
        params["control"] = {"seq": row.control_seq, "action": row.control_action}
    if row.resume_requested:
        params["resume_requested"] = True
    if row.finishing_since is not None:
        params["finishing_since"] = row.finishing_since.isoformat()
    if row.auto_resume is not None:
        params["auto_resume"] = row.auto_resume
    if row.live_progress is not None:
        params["live"] = row.live_progress
    if row.final_event is not None:
        params["service_finished"] = row.final_event
    return params


def upgrade() -> None:
    for column in _columns():
        op.add_column("run", column)
    with op.batch_alter_table("api_token") as batch:
        batch.add_column(sa.Column("operator", sa.String(100), server_default="", nullable=False))
    op.create_table(
        "run_audit",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("run_id", sa.String(length=64), nullable=False),
        sa.Column("at", db.types.UtcDateTime(), nullable=False),
        sa.Column("actor", sa.String(length=200), nullable=False),
        sa.Column(
            "action",
            sa.Enum(
                "start",
                "pause",
                "continue",
                "abort",
                "resume",
                "state",
                name="audit_action",
                native_enum=False,
                create_constraint=True,
                length=16,
            ),
            nullable=False,
        ),
        sa.Column(
            "state",
            sa.Enum(*RUN_STATES, name="audit_state", native_enum=False, create_constraint=True, length=16),
            nullable=True,
        ),
        sa.Column("detail", sa.Text(), nullable=False),
        sa.Column("window_index", sa.Integer(), nullable=True),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.ForeignKeyConstraint(
            ["run_id"], ["run.id"], name=op.f("fk_run_audit__run_id__run"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_run_audit")),
    )
    op.create_index(op.f("ix_run_audit__run_id"), "run_audit", ["run_id"], unique=False)
    conn = op.get_bind()
    for run_id, params in conn.execute(sa.select(_run.c.id, _run.c.params)).all():
        values, rest = _moved(params or {})
        conn.execute(sa.update(_run).where(_run.c.id == run_id).values(params=rest, **values))


def downgrade() -> None:
    conn = op.get_bind()
    rows = conn.execute(sa.select(_run)).all()
    for row in rows:
        conn.execute(sa.update(_run).where(_run.c.id == row.id).values(params=_restored(row)))
    op.drop_index(op.f("ix_run_audit__run_id"), table_name="run_audit")
    op.drop_table("run_audit")
    with op.batch_alter_table("api_token") as batch:
        batch.drop_column("operator")
    for column in reversed(_columns()):
        op.drop_column("run", column.name)
