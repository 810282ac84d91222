"""Alembic environment: metadata from ``db.models``, one chain for SQLite and PostgreSQL.

SQLite has almost no ``ALTER TABLE``, so on SQLite migrations render as batch operations
(copy the table, alter, swap), which is why every constraint has a name (``db.base``).
Run through :mod:`db.migrate`, which passes an open connection in
``config.attributes["connection"]``; a ``sqlalchemy.url`` main option also works.
"""

from __future__ import annotations

from alembic import context
from sqlalchemy.engine import Connection

import db.models
from db.engine import make_engine

config = context.config
target_metadata = db.models.Base.metadata


def _configure(connection: Connection) -> None:
    context.configure(
        connection=connection,
        target_metadata=target_metadata,
        render_as_batch=connection.dialect.name == "sqlite",
        transaction_per_migration=True,
        compare_type=True,
    )


def run_migrations_online() -> None:
    connection = config.attributes.get("connection")
    if connection is not None:
        _configure(connection)
        with context.begin_transaction():
            context.run_migrations()
        return
    engine = make_engine(config.get_main_option("sqlalchemy.url"))
    try:
        with engine.connect() as conn:
            _configure(conn)
            with context.begin_transaction():
                context.run_migrations()
    finally:
        engine.dispose()


if context.is_offline_mode():
    raise RuntimeError("offline (SQL script) migrations are not supported; run calbench db upgrade")
run_migrations_online()
