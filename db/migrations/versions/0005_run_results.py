"""Runs: the analysis results and the sample gaps out of ``params``, each in one typed home.

``params`` keeps the procedure's parameters only. The keys moved, with their homes:

=====================  ================================================================
``params`` key (0004)  home (0005)
=====================  ================================================================
``calibration``        ``fit_model.contract`` of the run's newest ``fit_model`` row
``diagnosis``          ``run.diagnosis`` (the ``calbench diagnose --json`` object)
``diagnosis_error``    ``run.diagnosis_error``
``certificate_error``  ``run.certificate_error``
``conformity_note``    ``run.conformity_note``
``sample_gaps``        ``sample_gap`` rows, one per gap, in order (``seq``)
=====================  ================================================================

The fit was stored twice (``params["calibration"]`` and a ``fit_model`` row, written
together). A run whose ``params["calibration"]`` equals its newest row's contract just drops
the copy; one without a row (a database written before the row existed) gets one (of the kind
the object states, :func:`bench.fit_kind.contract_kind`: ``dynamic`` for a ``dynamic-batch``
method, ``scalar`` for the orientation-free fit's terms, else ``static``; no covariance); one
whose copy differs from the row (a change written to one only) gets a new newest row with the
copy's contract and the row's kind, covariance and names, so neither is lost and the run shows
what it showed.

A value of the wrong shape for its home (a ``calibration`` or ``diagnosis`` that is not an
object, a note that is not text, a gap list whose entries are not gap records) stays in
``params`` as it was. The downgrade puts every value back under its key: ``diagnosis_error``
as ``null`` beside a stored diagnosis and ``sample_gaps`` (possibly ``[]``) for every run that
stored its sample count, as the code of 0004 wrote them; a gap record stored without
``window_label`` or ``daq_epoch`` comes back with their defaults (``""``, 0), and the
``fit_model`` rows the upgrade added stay.

Columns are added and dropped with ``ALTER TABLE`` on SQLite too (no batch copy: dropping the
copied ``run`` table would cascade to its child rows).

Revision ID: 0005
Revises: 0004
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import sqlalchemy as sa
from alembic import op

import db.types
from bench.fit_kind import contract_kind

revision: str = "0005"
down_revision: str | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

NOTES = ("diagnosis_error", "certificate_error", "conformity_note")
"""The text notes, one ``run`` column each under the same name."""
GAP_FIELDS: dict[str, tuple[type | tuple[type, ...], bool, int | None]] = {
    "first_lost_seq": (int, True, None),
    "n_lost": (int, True, None),
    "cause": (str, False, 16),
    "after_row": (int, False, None),
    "t_last_s": ((int, float), True, None),
    "t_resume_s": ((int, float), False, None),
    "window_index": (int, True, None),
    "window_label": (str, False, 100),
    "action": (str, False, 40),
    "daq_epoch": (int, False, None),
}
"""``bench.records.GapRecord`` as of this revision (frozen here): field -> (types, nullable,
max length), in the record's order."""
GAP_DEFAULTS = {"window_label": "", "daq_epoch": 0}


def _columns() -> tuple[sa.Column[Any], ...]:
    """The new ``run`` columns (fresh objects: a column belongs to one table)."""
    return (
        sa.Column("conformity_note", sa.Text(), nullable=True),
        sa.Column("diagnosis", sa.JSON(), nullable=True),
        sa.Column("diagnosis_error", sa.Text(), nullable=True),
        sa.Column("certificate_error", sa.Text(), nullable=True),
    )


_run = sa.table(
    "run",
    sa.column("id", sa.String),
    sa.column("params", sa.JSON),
    sa.column("n_samples", sa.BigInteger),
    *(sa.column(c.name, c.type) for c in _columns()),
)
_fit = sa.table(
    "fit_model",
    sa.column("id", sa.Integer),
    sa.column("run_id", sa.String),
    sa.column("kind", sa.String),
    sa.column("contract", sa.JSON),
    sa.column("param_names", sa.JSON),
    sa.column("covariance", sa.LargeBinary),
)
_gap = sa.table(
    "sample_gap",
    sa.column("run_id", sa.String),
    sa.column("seq", sa.Integer),
    sa.column("first_lost_seq", sa.BigInteger),
    sa.column("n_lost", sa.BigInteger),
    sa.column("cause", sa.String),
    sa.column("after_row", sa.BigInteger),
    sa.column("t_last_s", sa.Double),
    sa.column("t_resume_s", sa.Double),
    sa.column("window_index", sa.Integer),
    sa.column("window_label", sa.String),
    sa.column("action", sa.String),
    sa.column("daq_epoch", sa.Integer),
)
_MISSING = object()


def _gap_row(gap: object) -> dict[str, Any] | None:
    """A stored gap record as a ``sample_gap`` row's values, ``None`` if it is not one."""
    if not isinstance(gap, dict) or not set(gap) <= set(GAP_FIELDS):
        return None
    values = {**GAP_DEFAULTS, **gap}
    for name, (types, nullable, length) in GAP_FIELDS.items():
        if name not in values:
            return None
        value = values[name]
        if value is None and nullable:
            continue
        if isinstance(value, bool) or not isinstance(value, types):
            return None
        if length is not None and len(str(value)) > length:
            return None
    return values


def _moved(params: dict[str, Any]) -> tuple[dict[str, Any], Any, list[dict[str, Any]] | None, dict[str, Any]]:
    """(the ``run`` columns' values, the fit's contract or ``_MISSING``, the gap rows or ``None``,
    what stays in params) of one run's ``params``."""
    rest = dict(params)
    values: dict[str, Any] = {}
    calibration = rest.pop("calibration", _MISSING)
    if calibration is not _MISSING and not isinstance(calibration, dict):
        rest["calibration"], calibration = calibration, _MISSING
    diagnosis = rest.pop("diagnosis", None)
    if isinstance(diagnosis, dict):
        values["diagnosis"] = diagnosis
    elif diagnosis is not None:
        rest["diagnosis"] = diagnosis
    for name in NOTES:
        note = rest.pop(name, None)
        if isinstance(note, str):
            values[name] = note
        elif note is not None:
            rest[name] = note
    gaps = rest.pop("sample_gaps", None)
    rows = [_gap_row(g) for g in gaps] if isinstance(gaps, list) else None
    if rows is None or any(r is None for r in rows):
        if gaps is not None:
            rest["sample_gaps"] = gaps
        rows = None
    return values, calibration, [r for r in rows if r is not None] if rows is not None else None, rest


def _store_fit(conn: sa.Connection, run_id: str, contract: dict[str, Any]) -> None:
    """Make ``contract`` the run's newest fit row's contract without losing a row's."""
    newest = conn.execute(
        sa.select(_fit).where(_fit.c.run_id == run_id).order_by(_fit.c.id.desc()).limit(1)
    ).first()
    if newest is not None and newest.contract == contract:
        return
    row: dict[str, Any] = {
        "run_id": run_id,
        "contract": contract,
        "kind": contract_kind(contract).value,
        "param_names": [],
        "covariance": None,
    }
    if newest is not None:
        row.update(kind=newest.kind, param_names=newest.param_names, covariance=newest.covariance)
    conn.execute(sa.insert(_fit).values(**row))


def upgrade() -> None:
    for column in _columns():
        op.add_column("run", column)
    op.create_table(
        "sample_gap",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("run_id", sa.String(length=64), nullable=False),
        sa.Column("seq", sa.Integer(), nullable=False),
        sa.Column("first_lost_seq", sa.BigInteger(), nullable=True),
        sa.Column("n_lost", sa.BigInteger(), nullable=True),
        sa.Column("cause", sa.String(length=16), nullable=False),
        sa.Column("after_row", sa.BigInteger(), nullable=False),
        sa.Column("t_last_s", sa.Double(), nullable=True),
        sa.Column("t_resume_s", sa.Double(), nullable=False),
        sa.Column("window_index", sa.Integer(), nullable=True),
        sa.Column("window_label", sa.String(length=100), nullable=False),
        sa.Column("action", sa.String(length=40), nullable=False),
        sa.Column("daq_epoch", sa.Integer(), nullable=False),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.ForeignKeyConstraint(
            ["run_id"], ["run.id"], name=op.f("fk_sample_gap__run_id__run"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_sample_gap")),
        sa.UniqueConstraint("run_id", "seq", name=op.f("uq_sample_gap__run_id_seq")),
    )
    conn = op.get_bind()
    for run_id, params in conn.execute(sa.select(_run.c.id, _run.c.params)).all():
        values, calibration, gaps, rest = _moved(params or {})
        if calibration is not _MISSING:
            _store_fit(conn, run_id, calibration)
        for seq, gap in enumerate(gaps or ()):
            conn.execute(sa.insert(_gap).values(run_id=run_id, seq=seq, **gap))
        conn.execute(sa.update(_run).where(_run.c.id == run_id).values(params=rest, **values))


def _restored(row: Any, fit: dict[str, Any] | None, gaps: list[dict[str, Any]]) -> dict[str, Any]:
    """``params`` as revision 0004 kept it, from a run row, its newest fit's contract and its gaps."""
    params = dict(row.params or {})
    moved: dict[str, Any] = {}
    if fit is not None:
        moved["calibration"] = fit
    if row.diagnosis is not None:
        moved["diagnosis"], moved["diagnosis_error"] = row.diagnosis, row.diagnosis_error
    for name in NOTES:
        if getattr(row, name) is not None:
            moved[name] = getattr(row, name)
    if gaps or row.n_samples is not None:
        moved["sample_gaps"] = gaps
    return {**params, **{k: v for k, v in moved.items() if k not in params}}


def downgrade() -> None:
    conn = op.get_bind()
    newest = sa.select(sa.func.max(_fit.c.id)).group_by(_fit.c.run_id)
    fits = dict(conn.execute(sa.select(_fit.c.run_id, _fit.c.contract).where(_fit.c.id.in_(newest))).all())
    gaps: dict[str, list[dict[str, Any]]] = {}
    for gap in conn.execute(sa.select(_gap).order_by(_gap.c.run_id, _gap.c.seq)).all():
        gaps.setdefault(gap.run_id, []).append({name: getattr(gap, name) for name in GAP_FIELDS})
    for row in conn.execute(sa.select(_run)).all():
        params = _restored(row, fits.get(row.id), gaps.get(row.id, []))
        conn.execute(sa.update(_run).where(_run.c.id == row.id).values(params=params))
    op.drop_table("sample_gap")
    for column in reversed(_columns()):
        op.drop_column("run", column.name)
