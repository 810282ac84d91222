"""Engines for SQLite (embedded default) and PostgreSQL (many benches, one database).

The URL comes from ``CALBENCH_DATABASE_URL``; without it the database is
``sqlite:///<data_dir>/calbench.db`` with ``data_dir`` from ``CALBENCH_DATA_DIR`` or
``./data``. :func:`open_database` creates and migrates it on first start.

SQLite connections get ``journal_mode=WAL`` (readers never block the writer),
``foreign_keys=ON`` (SQLite ignores foreign keys otherwise), ``busy_timeout`` (wait for
a lock instead of failing) and ``synchronous=NORMAL`` (durable at each WAL checkpoint,
safe against process crashes). The driver's own transaction handling is switched off and
every transaction starts with ``BEGIN IMMEDIATE``: the write lock is taken up front, so
two writers queue on the busy timeout instead of failing on a lock upgrade, and
SAVEPOINTs and transactional DDL (Alembic) work (SQLAlchemy's pysqlite recipe).

Readers do not take that lock: a session from ``make_session_factory(engine, read_only=True)``
runs on the engine with the execution option ``calbench_read_only`` and its transactions
start with a plain (deferred) ``BEGIN``, so under WAL a read sees the last committed state
while a write transaction is open, instead of queueing behind it. Such a session refuses to
flush ORM changes (:class:`ReadOnlySessionError`), on every backend.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.orm import Session, sessionmaker

DATABASE_URL_ENV = "CALBENCH_DATABASE_URL"
DATA_DIR_ENV = "CALBENCH_DATA_DIR"
SQLITE_BUSY_TIMEOUT_MS = 30_000
READ_ONLY_OPTION = "calbench_read_only"
"""Execution option of a read-only engine: SQLite transactions start deferred."""


class ReadOnlySessionError(RuntimeError):
    """A read-only session was asked to write (a programming error, named by what it would write)."""


def default_data_dir(env: Mapping[str, str] | None = None) -> Path:
    """``CALBENCH_DATA_DIR`` or ``./data``."""
    env = os.environ if env is None else env
    return Path(env.get(DATA_DIR_ENV) or "data")


def default_database_url(env: Mapping[str, str] | None = None) -> str:
    """``CALBENCH_DATABASE_URL``, else ``sqlite:///<data_dir>/calbench.db``."""
    env = os.environ if env is None else env
    url = env.get(DATABASE_URL_ENV)
    if url:
        return url
    return f"sqlite:///{default_data_dir(env) / 'calbench.db'}"


def _decode_text(raw: bytes) -> str:
    """SQLite TEXT as str; bytes that are not UTF-8 (a row written by another tool) become U+FFFD
    in that one value instead of failing every query that reads the row."""
    return raw.decode("utf-8", "replace")


def _sqlite_on_connect(dbapi_connection: Any, _record: Any) -> None:
    dbapi_connection.isolation_level = None  # SQLAlchemy emits BEGIN itself (see _sqlite_on_begin)
    dbapi_connection.text_factory = _decode_text
    cur = dbapi_connection.cursor()
    try:
        cur.execute(f"PRAGMA busy_timeout = {SQLITE_BUSY_TIMEOUT_MS}")
        cur.execute("PRAGMA journal_mode = WAL")
        cur.execute("PRAGMA foreign_keys = ON")
        cur.execute("PRAGMA synchronous = NORMAL")
    finally:
        cur.close()


def _sqlite_on_begin(conn: sa.Connection) -> None:
    read_only = bool(conn.get_execution_options().get(READ_ONLY_OPTION))
    conn.exec_driver_sql("BEGIN" if read_only else "BEGIN IMMEDIATE")


def make_engine(url: str | sa.URL | None = None, **kwargs: Any) -> Engine:
    """An engine for ``url`` (default: :func:`default_database_url`).

    For a file SQLite database the parent directory is created. ``sqlite://`` in memory is
    refused: each connection would see its own empty database.

    :raises ValueError: unsupported or in-memory URL, naming it.
    """
    sa_url = make_url(url if url is not None else default_database_url())
    backend = sa_url.get_backend_name()
    if backend == "sqlite":
        database = sa_url.database or ""
        if database in ("", ":memory:") or database.startswith("file::memory:"):
            raise ValueError(f"database URL {sa_url!s}: in-memory SQLite is not supported, give a file path")
        Path(database).expanduser().parent.mkdir(parents=True, exist_ok=True)
        engine = sa.create_engine(sa_url, **kwargs)
        event.listen(engine, "connect", _sqlite_on_connect)
        event.listen(engine, "begin", _sqlite_on_begin)
        return engine
    if backend == "postgresql":
        if sa_url.drivername == "postgresql":
            sa_url = sa_url.set(drivername="postgresql+psycopg")  # psycopg 3 is the installed driver
        kwargs.setdefault("pool_pre_ping", True)
        return sa.create_engine(sa_url, **kwargs)
    raise ValueError(
        f"database URL {sa_url.render_as_string(hide_password=True)}: backend {backend!r} not supported "
        "(use sqlite:///PATH or postgresql+psycopg://USER@HOST/DB)"
    )


def _refuse_writes(session: Session, _context: Any, _instances: Any) -> None:
    if session.info.get(READ_ONLY_OPTION) and (session.new or session.dirty or session.deleted):
        changed = [type(o).__name__ for o in (*session.new, *session.dirty, *session.deleted)]
        raise ReadOnlySessionError(f"read-only session asked to write {', '.join(sorted(set(changed)))}")


def make_session_factory(engine: Engine, *, read_only: bool = False) -> sessionmaker[Session]:
    """``sessionmaker`` bound to ``engine``; use ``with factory.begin() as session:``.

    ``expire_on_commit=False`` so objects read in a transaction stay usable after it.

    :param read_only: sessions for reading only: on SQLite their transactions begin deferred
        (no write lock, not blocked by an open write transaction); a flush with changes
        raises :class:`ReadOnlySessionError`.
    """
    if not read_only:
        return sessionmaker(engine, expire_on_commit=False)
    factory = sessionmaker(
        engine.execution_options(**{READ_ONLY_OPTION: True}),
        expire_on_commit=False,
        info={READ_ONLY_OPTION: True},
    )
    if not event.contains(factory, "before_flush", _refuse_writes):
        event.listen(factory, "before_flush", _refuse_writes)
    return factory


def describe_connection_error(url: str | sa.URL | None, exc: BaseException) -> str:
    """One line naming the database (password hidden) and the driver's first error line."""
    sa_url = make_url(url if url is not None else default_database_url())
    detail = str(getattr(exc, "orig", None) or exc).strip().splitlines()
    return (
        f"cannot use database {sa_url.render_as_string(hide_password=True)}: {detail[0] if detail else exc}"
    )
