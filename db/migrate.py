"""Alembic driven from code: no ``alembic.ini`` needed, works from an installed package.

``upgrade(engine_or_url)`` brings a database to the newest revision of the single chain
in ``db/migrations/versions`` (the same chain for SQLite and PostgreSQL). On PostgreSQL
the upgrade holds an advisory lock, so several benches starting at once against one
database migrate it once, one after the other.
"""

from __future__ import annotations

from pathlib import Path

import sqlalchemy as sa
from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy.engine import Engine

from db.engine import make_engine

MIGRATIONS_DIR = Path(__file__).resolve().parent / "migrations"
_PG_MIGRATION_LOCK_KEY = 0x63616C62  # "calb"


def alembic_config(connection: sa.Connection | None = None) -> Config:
    """An Alembic ``Config`` pointing at ``db/migrations``; ``connection`` is handed to env.py."""
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    cfg.set_main_option("path_separator", "os")
    if connection is not None:
        cfg.attributes["connection"] = connection
    return cfg


def _as_engine(engine_or_url: Engine | str | sa.URL) -> tuple[Engine, bool]:
    if isinstance(engine_or_url, Engine):
        return engine_or_url, False
    return make_engine(engine_or_url), True


def upgrade(engine_or_url: Engine | str | sa.URL, revision: str = "head") -> None:
    """Upgrade the database to ``revision`` (default: the newest)."""
    engine, owned = _as_engine(engine_or_url)
    try:
        with engine.connect() as conn:
            is_pg = conn.dialect.name == "postgresql"
            if is_pg:
                conn.execute(sa.text("SELECT pg_advisory_lock(:k)"), {"k": _PG_MIGRATION_LOCK_KEY})
                conn.commit()
            try:
                command.upgrade(alembic_config(conn), revision)
            finally:
                if is_pg:
                    conn.rollback()
                    conn.execute(sa.text("SELECT pg_advisory_unlock(:k)"), {"k": _PG_MIGRATION_LOCK_KEY})
                    conn.commit()
    finally:
        if owned:
            engine.dispose()


def downgrade(engine_or_url: Engine | str | sa.URL, revision: str) -> None:
    """Downgrade the database to ``revision`` (``base`` empties it)."""
    engine, owned = _as_engine(engine_or_url)
    try:
        with engine.connect() as conn:
            command.downgrade(alembic_config(conn), revision)
    finally:
        if owned:
            engine.dispose()


def current_revision(engine: Engine) -> str | None:
    """The revision the database is at, or ``None`` for an empty database."""
    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()


def head_revision() -> str | None:
    """The newest revision of the chain."""
    return ScriptDirectory.from_config(alembic_config()).get_current_head()


def open_database(url: str | sa.URL | None = None) -> Engine:
    """The engine for ``url``, with the schema created or upgraded to the newest revision."""
    engine = make_engine(url)
    upgrade(engine)
    return engine
