"""``INSERT … ON CONFLICT DO NOTHING`` on SQLite and PostgreSQL."""

from __future__ import annotations

from typing import Any

from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session


def insert_or_ignore(
    session: Session, model: type[Any], values: dict[str, Any], conflict_cols: list[str]
) -> None:
    """Insert ``values`` into ``model``'s table unless a row with the same ``conflict_cols`` exists.

    Race-free: on PostgreSQL a concurrent insert of the same key waits for the other
    transaction and then does nothing, so get-or-create never fails with a duplicate key.
    """
    dialect = session.get_bind().dialect.name
    if dialect == "postgresql":
        stmt: Any = (
            postgresql.insert(model).values(**values).on_conflict_do_nothing(index_elements=conflict_cols)
        )
    elif dialect == "sqlite":
        stmt = sqlite.insert(model).values(**values).on_conflict_do_nothing(index_elements=conflict_cols)
    else:  # pragma: no cover - make_engine refuses other backends
        raise ValueError(f"unsupported database dialect {dialect!r}")
    session.execute(stmt)
