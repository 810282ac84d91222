"""On PostgreSQL a NUL byte in text is a psycopg DataError: every way one can arrive answers 4xx."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from fastapi import FastAPI
from fastapi.testclient import TestClient

from api.error_handlers import install_error_handlers
from api.main import create_app
from tests.support.service_helpers import OP, VIEW, service_settings

pytestmark = [pytest.mark.postgres, pytest.mark.timeout(180)]


@pytest.fixture()
def client(tmp_path: Path, pg_url: str) -> Iterator[TestClient]:
    settings = service_settings(tmp_path, database_url=pg_url)
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        yield c


@pytest.mark.parametrize(
    ("method", "url", "body"),
    [
        ("GET", "/api/runs?unit_serial=SN%00", None),
        ("GET", "/api/units/SN%00/history", None),
        ("GET", "/api/certificates/C%00", None),
        ("PUT", "/api/units/SN-PG", {"customer_name": "Acme\x00"}),
        ("PUT", "/api/units/SN-PG", {"condition": "ok\x00"}),
        ("POST", "/api/runs", {"unit_serial": "SN\x00", "procedure": "static-12"}),
    ],
)
def test_nul_byte_is_4xx_on_postgresql(client: TestClient, method: str, url: str, body: object) -> None:
    r = client.request(method, url, json=body, headers=OP if method != "GET" else VIEW)
    assert 400 <= r.status_code < 500, (r.status_code, r.text)


def test_a_data_error_from_psycopg_is_422(pg_url: str) -> None:
    engine = sa.create_engine(pg_url)
    app = FastAPI()
    install_error_handlers(app)

    @app.get("/echo")
    def echo(text: str) -> str:
        with engine.connect() as conn:
            return str(conn.execute(sa.text("SELECT CAST(:t AS text)"), {"t": text}).scalar())

    with TestClient(app) as c:
        assert c.get("/echo", params={"text": "ok"}).json() == "ok"
        r = c.get("/echo", params={"text": "a\x00b"})
    engine.dispose()
    assert r.status_code == 422 and "cannot store" in r.json()["detail"]
