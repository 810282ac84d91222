"""Throw-away PostgreSQL databases on the machine's server, and database fixtures to reuse.

The server is ``127.0.0.1:5432`` with trust auth (override with ``CALBENCH_TEST_PG_URL``,
a URL of a database the user may ``CREATE DATABASE`` from). :func:`pg_database` creates
``calbench_<random>`` and drops it afterwards.

To reuse the fixtures in another test package, import them into its ``conftest.py``::

    from tests.pg import db_backend, db_engine, db_session_factory, pg_server  # noqa: F401

``db_engine`` is then parametrised over ``sqlite`` (a fresh file per test) and
``postgresql`` (one database per test session, emptied after each test); ``empty_engine``
likewise, with no schema (a new database per test, for migration tests); the PostgreSQL case
is skipped with the reason when the server cannot be reached.
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import sqlalchemy as sa
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session, sessionmaker

ADMIN_URL = os.environ.get("CALBENCH_TEST_PG_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test")


def pg_unreachable_reason(admin_url: str = ADMIN_URL) -> str | None:
    """``None`` when the server answers, else why not (for ``pytest.skip``)."""
    engine = sa.create_engine(admin_url, connect_args={"connect_timeout": 3})
    try:
        with engine.connect() as conn:
            conn.execute(sa.text("SELECT 1"))
    except Exception as exc:
        return (
            f"PostgreSQL at {sa.make_url(admin_url).render_as_string(hide_password=True)} unreachable: {exc}"
        )
    finally:
        engine.dispose()
    return None


@contextmanager
def pg_database(admin_url: str = ADMIN_URL) -> Iterator[str]:
    """Create a fresh database ``calbench_<random>``, yield its URL, drop it on exit."""
    name = f"calbench_{secrets.token_hex(6)}"
    admin = sa.create_engine(admin_url, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as conn:
            conn.execute(sa.text(f'CREATE DATABASE "{name}"'))
        yield sa.make_url(admin_url).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as conn:
            conn.execute(sa.text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()


def truncate_all(engine: Engine) -> None:
    """Empty every calbench table (PostgreSQL) and restart the id sequences."""
    import db.models

    names = ", ".join(f'"{t.name}"' for t in db.models.Base.metadata.sorted_tables)
    with engine.begin() as conn:
        conn.execute(sa.text(f"TRUNCATE {names} RESTART IDENTITY CASCADE"))


@pytest.fixture(scope="session")
def pg_server() -> Iterator[str]:
    """URL of a migrated PostgreSQL database for this test session (skips if no server)."""
    reason = pg_unreachable_reason()
    if reason:
        pytest.skip(reason)
    from db.migrate import upgrade

    with pg_database() as url:
        upgrade(url)
        yield url


@pytest.fixture(scope="module")
def pg_url() -> Iterator[str]:
    """URL of a fresh, empty PostgreSQL database for one test module (skips if no server)."""
    reason = pg_unreachable_reason()
    if reason:
        pytest.skip(reason)
    with pg_database() as url:
        yield url


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def db_backend(request: pytest.FixtureRequest) -> str:
    """``"sqlite"`` or ``"postgresql"``."""
    return str(request.param)


@pytest.fixture
def db_engine(db_backend: str, request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Engine]:
    """A migrated, empty calbench database on each backend."""
    from db.engine import make_engine
    from db.migrate import upgrade

    if db_backend == "sqlite":
        engine = make_engine(f"sqlite:///{tmp_path / 'calbench.db'}")
        upgrade(engine)
        yield engine
        engine.dispose()
        return
    url = request.getfixturevalue("pg_server")
    engine = make_engine(url)
    try:
        yield engine
    finally:
        truncate_all(engine)
        engine.dispose()


@pytest.fixture
def empty_engine(db_backend: str, tmp_path: Path) -> Iterator[Engine]:
    """A fresh database with no schema at all on each backend, for migration tests that build
    an older revision themselves (a new PostgreSQL database per test: a downgrade to base leaves
    nothing to empty)."""
    from db.engine import make_engine

    if db_backend == "sqlite":
        engine = make_engine(f"sqlite:///{tmp_path / 'empty.db'}")
        yield engine
        engine.dispose()
        return
    reason = pg_unreachable_reason()
    if reason:
        pytest.skip(reason)
    with pg_database() as url:
        engine = make_engine(url)
        try:
            yield engine
        finally:
            engine.dispose()


@pytest.fixture
def db_session_factory(db_engine: Engine) -> sessionmaker[Session]:
    """``sessionmaker`` on :func:`db_engine`; use ``with factory.begin() as s:``."""
    from db.engine import make_session_factory

    return make_session_factory(db_engine)
