"""The one Alembic chain: head matches the models on both dialects; SQLite pragmas."""

from __future__ import annotations

import pytest
import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy.exc import IntegrityError

import db.models
from db.engine import default_database_url, make_engine
from db.migrate import current_revision, downgrade, head_revision, open_database, upgrade


def _diff(engine):
    with engine.connect() as conn:
        ctx = MigrationContext.configure(conn, opts={"compare_type": True, "compare_server_default": False})
        return compare_metadata(ctx, db.models.Base.metadata)


def test_upgrade_head_leaves_no_autogenerate_diff(db_engine):
    assert current_revision(db_engine) == head_revision()
    assert _diff(db_engine) == []


def test_downgrade_to_base_and_up_again(empty_engine):
    upgrade(empty_engine)
    downgrade(empty_engine, "base")
    assert set(sa.inspect(empty_engine).get_table_names()) <= {"alembic_version"}
    upgrade(empty_engine)
    assert _diff(empty_engine) == []


def test_sqlite_pragmas_wal_and_foreign_keys(tmp_path):
    engine = make_engine(f"sqlite:///{tmp_path / 'p.db'}")
    with engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        assert conn.exec_driver_sql("PRAGMA busy_timeout").scalar() >= 1000
    engine.dispose()


def test_sqlite_enforces_foreign_keys(tmp_path):
    engine = open_database(f"sqlite:///{tmp_path / 'fk.db'}")
    with pytest.raises(IntegrityError), engine.begin() as conn:
        conn.execute(
            sa.text("INSERT INTO unit (serial, bench_id, created_at) VALUES ('x', 999, '2025-01-01')")
        )
    engine.dispose()


def test_first_start_creates_and_migrates_default_database(tmp_path, monkeypatch):
    monkeypatch.delenv("CALBENCH_DATABASE_URL", raising=False)
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path / "fresh" / "dir"))
    url = default_database_url()
    assert url == f"sqlite:///{tmp_path / 'fresh' / 'dir' / 'calbench.db'}"
    engine = open_database()
    assert (tmp_path / "fresh" / "dir" / "calbench.db").is_file()
    assert current_revision(engine) == head_revision()
    open_database().dispose()  # second start: already at head, no error
    engine.dispose()


def test_database_url_from_environment(monkeypatch):
    monkeypatch.setenv("CALBENCH_DATABASE_URL", "postgresql+psycopg://u@h/db")
    assert default_database_url() == "postgresql+psycopg://u@h/db"


def test_bad_urls_are_refused_with_the_url_named():
    with pytest.raises(ValueError, match="in-memory"):
        make_engine("sqlite://")
    with pytest.raises(ValueError, match="mysql"):
        make_engine("mysql://u@h/db")


def test_plain_postgresql_url_uses_psycopg3():
    engine = make_engine("postgresql://postgres@127.0.0.1:5432/test")
    assert engine.dialect.driver == "psycopg"
    engine.dispose()
