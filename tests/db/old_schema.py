"""What the migration tests build an older revision from: the tables as every revision since
0003 has them (not the models: they follow the newest revision), a run's stored setup, and a
database at a given revision with one bench and one unit."""

from __future__ import annotations

from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Engine

from db.migrate import current_revision, upgrade

BENCH = sa.table("bench", sa.column("id", sa.Integer), sa.column("name", sa.String))
UNIT = sa.table("unit", sa.column("id", sa.Integer), sa.column("serial", sa.String))


def run_table(*later: sa.ColumnClause[Any]) -> sa.TableClause:
    """The ``run`` table with the columns every revision since 0003 has and ``later`` ones."""
    return sa.table(
        "run",
        sa.column("id", sa.String),
        sa.column("unit_id", sa.Integer),
        sa.column("bench_id", sa.Integer),
        sa.column("procedure", sa.String),
        sa.column("state", sa.String),
        sa.column("progress", sa.Float),
        sa.column("params", sa.JSON),
        sa.column("resume_count", sa.Integer),
        sa.column("limit_checks", sa.JSON),
        *later,
    )


SETUP: dict[str, Any] = {
    "procedure": "static-12",
    "parameters": {"dwell_s": 3.0, "n_poses": 12},
    "sim": {"seed": 7},
    "bench": "bench-a",
    "bench_config": {"name": "sim", "version": 1, "sha256": "ab" * 32},
    "sample_rate_hz": 100.0,
    "n_axes": 3,
    "n_windows": 12,
    "expected_duration_s": 96.0,
    "dwell": {"dwell_s": 3.0, "source": "fixed", "reason": "given", "details": {}},
}
"""A run's setup as the service stores it in ``params`` (bench 1 "bench-a", unit 1 "SN-1")."""


def at_revision(engine: Engine, revision: str) -> None:
    """Migrate the empty database ``engine`` up to ``revision`` and add bench 1 and unit 1."""
    upgrade(engine, revision)
    assert current_revision(engine) == revision
    with engine.begin() as conn:
        conn.execute(sa.insert(BENCH).values(id=1, name="bench-a"))
        conn.execute(sa.insert(UNIT).values(id=1, serial="SN-1"))


def row_counts(engine: Engine, tables: tuple[str, ...]) -> dict[str, int]:
    """The number of rows of each of ``tables``."""
    with engine.connect() as conn:
        return {t: int(conn.scalar(sa.text(f"SELECT count(*) FROM {t}")) or 0) for t in tables}
