"""Fixtures of the API tests shared from the test support modules."""

from tests.pg import pg_url  # noqa: F401
