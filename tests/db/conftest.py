"""Database fixtures for tests/db: every test runs on SQLite and on PostgreSQL."""

from tests.pg import db_backend, db_engine, db_session_factory, empty_engine, pg_server  # noqa: F401
