"""Every service case of issue 13 answers 4xx, or is refused before its body is read.

The body-size and authentication cases drive the ASGI app directly with a ``receive`` that
counts the chunks it hands out, so "refused before reading" is measured, not assumed.
"""

from __future__ import annotations

import json
import logging
import sqlite3
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from api.auth import LinkSigner, Principal, Role
from api.guard import MAX_JSON_BODY_BYTES
from api.log_redaction import RedactSecrets
from api.main import create_app
from api.startup_check import ConfigError, check_configuration
from tests.support.service_helpers import OP, OPERATOR, VIEW, service_settings, signed_link

pytestmark = pytest.mark.timeout(120)
ADMIN_SECRET = "admin-secret-0001"
ADMIN = {"Authorization": f"Bearer {ADMIN_SECRET}"}
MB = 1024 * 1024


@pytest.fixture()
def client(tmp_path: Path) -> Iterator[TestClient]:
    settings = service_settings(tmp_path)
    settings = settings.model_copy(update={"tokens": [*settings.tokens, f"admin:{ADMIN_SECRET}"]})
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        yield c


def _raw(
    client: TestClient,
    method: str,
    path: str,
    headers: dict[str, str],
    chunks: int,
    chunk_bytes: int = MB,
) -> tuple[int, int, dict[str, str]]:
    """Send a request whose body is ``chunks`` chunks straight to the ASGI app.

    :returns: status, number of chunks the app asked for, response headers.
    """
    asked = 0
    status: list[int] = []
    resp_headers: dict[str, str] = {}

    async def receive() -> dict[str, Any]:
        nonlocal asked
        asked += 1
        more = asked < chunks
        return {"type": "http.request", "body": b"x" * chunk_bytes, "more_body": more}

    async def send(message: dict[str, Any]) -> None:
        if message["type"] == "http.response.start":
            status.append(message["status"])
            resp_headers.update({k.decode(): v.decode() for k, v in message["headers"]})

    scope = {
        "type": "http",
        "asgi": {"version": "3.0"},
        "http_version": "1.1",
        "method": method,
        "scheme": "http",
        "path": path,
        "raw_path": path.encode(),
        "query_string": b"",
        "root_path": "",
        "headers": [(k.lower().encode(), v.encode()) for k, v in headers.items()],
        "client": ("127.0.0.1", 1234),
        "server": ("testserver", 80),
    }
    assert client.portal is not None
    client.portal.call(client.app, scope, receive, send)
    return status[0], asked, resp_headers


def test_unauthenticated_200mb_json_body_is_refused_unread(client: TestClient) -> None:
    headers = {"content-type": "application/json", "content-length": str(200 * MB)}
    status, asked, _ = _raw(client, "POST", "/api/runs", headers, chunks=200)
    assert (status, asked) == (413, 0)


def test_unauthenticated_upload_is_refused_before_a_byte_is_stored(client: TestClient) -> None:
    big = {"content-type": "multipart/form-data; boundary=x", "content-length": str(1420 * MB)}
    assert _raw(client, "POST", "/api/recordings", big, chunks=1420)[:2] == (413, 0)
    small = {"content-type": "multipart/form-data; boundary=x", "content-length": str(10 * MB)}
    status, asked, headers = _raw(client, "POST", "/api/recordings", small, chunks=10)
    assert (status, asked) == (401, 0)
    assert headers["www-authenticate"] == "Bearer"


def test_chunked_body_without_length_is_refused_unread_without_token(client: TestClient) -> None:
    status, asked, _ = _raw(client, "POST", "/api/runs", {"content-type": "application/json"}, chunks=100)
    assert (status, asked) == (401, 0)


def test_viewer_cannot_make_the_service_read_a_body(client: TestClient) -> None:
    headers = {"content-type": "application/json", "content-length": "100", **VIEW}
    assert _raw(client, "POST", "/api/runs", headers, chunks=1, chunk_bytes=100)[:2] == (403, 0)


def test_chunked_body_past_the_limit_stops_at_the_limit(client: TestClient) -> None:
    headers = {"content-type": "application/json", **OP}
    status, asked, _ = _raw(client, "POST", "/api/runs", headers, chunks=100)
    assert status == 413
    assert asked <= MAX_JSON_BODY_BYTES // MB + 1


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999", "1e-300"])
def test_non_finite_dwell_is_422(client: TestClient, literal: str) -> None:
    body = '{"unit_serial": "SN-1", "procedure": "static-12", "dwell_s": ' + literal + "}"
    r = client.post("/api/runs", content=body, headers={**OP, "content-type": "application/json"})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"][-1] == "dwell_s"


@pytest.mark.parametrize("field", ["nominal_scale", "nominal_bias"])
@pytest.mark.parametrize("literal", ["NaN", "Infinity", "1e999"])
def test_non_finite_unit_numbers_are_422(client: TestClient, field: str, literal: str) -> None:
    body = f'{{"{field}": {literal}}}'
    r = client.put("/api/units/SN-NF", content=body, headers={**OP, "content-type": "application/json"})
    assert r.status_code == 422, r.text
    assert field in json.dumps(r.json())


def test_token_id_beyond_64_bits_is_422(client: TestClient) -> None:
    r = client.delete("/api/tokens/" + "9" * 23, headers=ADMIN)
    assert r.status_code == 422, r.text


def _upload(client: TestClient, sidecar_text: str) -> Any:
    csv = "t,ax,ay,az\n" + "".join(f"{i / 100},0,0,9.8\n" for i in range(10))
    files = {
        "recording": ("run.csv", csv, "text/csv"),
        "sidecar": ("run.json", sidecar_text, "application/json"),
    }
    return client.post("/api/recordings", files=files, headers=OP)


SIDECAR = {
    "format": "calbench-recording/1",
    "unit": {"serial": "SN-U"},
    "channel_unit": "m/s2",
    "sample_rate_hz": 100.0,
    "g_local_m_s2": 9.81,
}


def test_deeply_nested_sidecar_upload_is_422(client: TestClient) -> None:
    text = json.dumps(SIDECAR)[:-1] + ', "x": ' + "[" * 100_000 + "]" * 100_000 + "}"
    r = _upload(client, text)
    assert r.status_code == 422 and "nested deeper" in r.json()["detail"]


def test_huge_integer_sidecar_upload_is_422(client: TestClient) -> None:
    r = _upload(client, json.dumps(SIDECAR).replace("100.0", "9" * 400))
    assert r.status_code == 422 and "digits" in r.json()["detail"]


@pytest.mark.parametrize(
    "body",
    [{"customer_name": "Acme\x00"}, {"model": "ADXL\u202e"}, {"customer_address": "1 Main St\u202eTown"}],
)
def test_nul_and_bidi_in_stored_text_are_422(client: TestClient, body: dict[str, str]) -> None:
    r = client.put("/api/units/SN-TXT", json=body, headers=OP)
    assert r.status_code == 422, r.text


def test_multiline_address_is_kept(client: TestClient) -> None:
    r = client.put("/api/units/SN-TXT", json={"customer_address": "1 Main St\nTown"}, headers=OP)
    assert r.status_code == 200 and r.json()["customer_address"] == "1 Main St\nTown"


def test_nul_in_token_label_is_422(client: TestClient) -> None:
    assert (
        client.post("/api/tokens", json={"role": "viewer", "label": "a\x00b"}, headers=ADMIN).status_code
        == 422
    )


@pytest.mark.parametrize(
    "url", ["/api/runs?unit_serial=a%00b", "/api/runs/a%00b", "/api/units/SN%00/history"]
)
def test_nul_in_path_or_query_is_400(client: TestClient, url: str) -> None:
    assert client.get(url, headers=VIEW).status_code == 400


def test_security_headers_on_every_response(client: TestClient) -> None:
    for url in ("/", "/api/health", "/static/app.js", "/api/runs"):
        r = client.get(url)
        csp = r.headers["content-security-policy"]
        assert "script-src 'self'" in csp and "frame-ancestors 'none'" in csp, url
        assert r.headers["x-frame-options"] == "DENY"
        assert r.headers["x-content-type-options"] == "nosniff"


def test_health_without_token_shows_no_database_path(client: TestClient, tmp_path: Path) -> None:
    body = client.get("/api/health").json()
    assert body["database"] == "sqlite"
    assert str(tmp_path) not in json.dumps(body)


def test_token_in_the_url_is_not_accepted(client: TestClient) -> None:
    r = client.post("/api/runs", json={"unit_serial": "SN-L", "procedure": "static-12"}, headers=OP)
    run_id = r.json()["id"]
    assert client.get(f"/api/runs/{run_id}/certificate.pdf?access_token={OPERATOR}").status_code == 401


def test_signed_link_is_for_one_path_and_expires(client: TestClient) -> None:
    url = signed_link(client, "/api/runs/R-1/certificate.pdf", headers=VIEW)
    link = url.split("?link=")[1]
    assert client.get(url).status_code == 404  # accepted: the run does not exist
    assert client.get(f"/api/runs/R-2/certificate.pdf?link={link}").status_code == 401
    assert client.get(f"/api/runs/R-1/certificate.pdf?link={link[:-2]}xx").status_code == 401
    assert client.get("/api/runs/R-1/certificate.pdf", params={"link": "é.é"}).status_code == 401
    signer = LinkSigner(key=b"k" * 32, clock=lambda: 1000.0)
    old, _ = signer.sign("/p", Principal(Role.VIEWER), ttl_s=60)
    assert signer.verify(old, "/p").role is Role.VIEWER
    late = LinkSigner(key=b"k" * 32, clock=lambda: 1061.0)
    with pytest.raises(Exception, match="expired"):
        late.verify(old, "/p")


def test_links_only_for_pdf_and_events(client: TestClient) -> None:
    r = client.post("/api/links", json={"path": "/api/tokens"}, headers=VIEW)
    assert r.status_code == 422
    assert client.post("/api/links", json={"path": "/api/runs/R-1/events"}).status_code == 401


def test_link_dies_with_its_revoked_token(client: TestClient) -> None:
    made = client.post("/api/tokens", json={"role": "viewer", "label": "screen"}, headers=ADMIN).json()
    url = signed_link(
        client, "/api/runs/R-1/certificate.pdf", headers={"Authorization": f"Bearer {made['secret']}"}
    )
    assert client.get(url).status_code == 404
    assert client.delete(f"/api/tokens/{made['id']}", headers=ADMIN).status_code == 200
    r = client.get(url)
    assert r.status_code == 401 and "revoked" in r.json()["detail"]


def test_event_stream_ends_when_its_token_is_revoked(client: TestClient) -> None:
    made = client.post("/api/tokens", json={"role": "viewer", "label": "wall"}, headers=ADMIN).json()
    viewer = {"Authorization": f"Bearer {made['secret']}"}
    run_id = client.post(
        "/api/runs", json={"unit_serial": "SN-REV", "procedure": "static-12", "dwell_s": 30}, headers=OP
    ).json()["id"]
    names: list[str] = []
    revoked_at = None
    with client.stream("GET", f"/api/runs/{run_id}/events", headers=viewer) as s:
        for line in s.iter_lines():
            if line.startswith("event: "):
                names.append(line[7:])
                if revoked_at is None:
                    assert client.delete(f"/api/tokens/{made['id']}", headers=ADMIN).status_code == 200
                    revoked_at = time.monotonic()
            if line.startswith("data: ") and names and names[-1] == "shutdown":
                assert "revoked" in line
    assert revoked_at is not None and names[-1] == "shutdown"
    assert time.monotonic() - revoked_at < 10.0
    client.post(f"/api/runs/{run_id}/abort", headers=OP)


def test_a_run_aborted_while_queued_does_not_hold_the_bench(tmp_path: Path) -> None:
    """Nobody ever owned it, so nobody is storing its results: the bench is free at once. The
    agent is another process that is not running, so the run stays queued until the abort."""
    settings = service_settings(tmp_path, agent="external")
    with TestClient(create_app(settings, start_scheduler=False)) as client:
        run_id = client.post(
            "/api/runs", json={"unit_serial": "SN-QAB", "procedure": "static-12"}, headers=OP
        ).json()["id"]
        assert client.post(f"/api/runs/{run_id}/abort", headers=OP).json()["state"] == "aborted"
        assert client.app.state.services.runner.current is None  # type: ignore[attr-defined]
        assert client.get(f"/api/runs/{run_id}", headers=OP).json()["state"] == "aborted"


def test_invalid_utf8_in_one_run_does_not_break_the_list(client: TestClient, tmp_path: Path) -> None:
    run_id = client.post(
        "/api/runs", json={"unit_serial": "SN-BAD", "procedure": "static-12"}, headers=OP
    ).json()["id"]
    client.post(f"/api/runs/{run_id}/abort", headers=OP)
    deadline = time.monotonic() + 60
    while client.app.state.services.runner.current is not None and time.monotonic() < deadline:  # type: ignore[attr-defined]
        time.sleep(0.1)
    con = sqlite3.connect(tmp_path / "calbench.db")
    with con:
        con.execute("UPDATE run SET params = CAST(X'7B2261223A2022FF22207D' AS TEXT) WHERE id = ?", (run_id,))
    con.close()
    r = client.get("/api/runs", headers=VIEW)
    assert r.status_code == 200, r.text
    assert run_id in [x["id"] for x in r.json()]
    assert client.get("/api/units/SN-BAD/history", headers=VIEW).status_code == 200


def test_startup_refuses_a_bad_device_url_and_an_empty_database(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="CALBENCH_TABLE_URL 'ftp://x': unknown scheme"):
        check_configuration(
            service_settings(tmp_path, sim=False, table_url="ftp://x", daq_url="modbus-tcp://h:502")
        )
    with pytest.raises(ConfigError, match="CALBENCH_DAQ_URL 'http://h': unknown scheme"):
        check_configuration(
            service_settings(tmp_path, sim=False, table_url="socket://h:1", daq_url="http://h")
        )
    check_configuration(
        service_settings(tmp_path, sim=False, table_url="socket://h:1", daq_url="modbus-tcp://h:502")
    )
    (tmp_path / "calbench.db").write_bytes(b"")
    with pytest.raises(ConfigError, match="zero-length"):
        check_configuration(service_settings(tmp_path))
    with pytest.raises(ConfigError, match="zero-length"), TestClient(create_app(service_settings(tmp_path))):
        pass
    assert (tmp_path / "calbench.db").stat().st_size == 0  # not silently recreated
    with pytest.raises(ConfigError, match="CALBENCH_RUN_DWELL_S"):
        check_configuration(service_settings(tmp_path / "x", run_dwell_s=1e-300))


def test_startup_refuses_bidi_in_certificate_texts(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="CALBENCH_LAB_ADDRESS"):
        check_configuration(service_settings(tmp_path, lab_address="Main St \u202e 1"))


def test_access_log_never_shows_a_credential_in_a_url() -> None:
    args = ("127.0.0.1:5", "GET", "/api/runs/R-1/events?access_token=SECRET1&x=1&link=abc.def", "1.1", 200)
    record = logging.LogRecord("uvicorn.access", logging.INFO, "", 0, '%s - "%s %s HTTP/%s" %d', args, None)
    assert RedactSecrets().filter(record)
    line = record.getMessage()
    assert "SECRET1" not in line and "abc.def" not in line
    assert "access_token=REDACTED&x=1&link=REDACTED" in line


def test_serve_refuses_a_bad_device_url_on_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from api.cli import main

    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CALBENCH_TABLE_URL", "gopher://bench")
    monkeypatch.setenv("CALBENCH_DAQ_URL", "modbus-tcp://127.0.0.1:5020")
    monkeypatch.setenv("CALBENCH_TOKENS", f"operator:{OPERATOR}")
    assert main(["serve"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "CALBENCH_TABLE_URL 'gopher://bench': unknown scheme 'gopher'" in err


@pytest.mark.parametrize("arg", ["1_0", "١٢", "nan"])
def test_cli_numbers_are_ascii_decimal(arg: str, capsys: pytest.CaptureFixture[str]) -> None:
    from api.cli import main

    with pytest.raises(SystemExit) as info:
        main(["calibrate", "x.csv", "--nominal-scale", arg])
    assert info.value.code == 2 and "--nominal-scale" in capsys.readouterr().err


def test_pdf_never_prints_a_bidi_control_stored_before_the_rules() -> None:
    from station.certificates.pdf_layout import Flow

    flow = Flow(top=0.95, bottom=0.05, left=0.1, right=0.9)
    flow.paragraph("Customer: ACME, 1 Main St \u202eTown")
    texts = [t for page in flow.pages for t in page.texts()]
    assert any("1 Main St ?Town" in t for t in texts), texts
    assert not any("\u202e" in t for t in texts)


@pytest.mark.parametrize(
    "body",
    [
        '{"unit_serial": "SN-1", "procedure": "static-12", "dwell_s": ' + "9" * 5000 + "}",
        '{"unit_serial": "SN-1", "procedure": "static-12", "x": ' + "[" * 200_000 + "]" * 200_000 + "}",
        '{"unit_serial": "SN-1", "procedure": "static-12", "dwell_s": 10, "dwell_s": 20}',
        '{"unit_serial": "SN-1", "procedure": "static-12" "dwell_s": 10}',
        "\xff\xfe",
    ],
)
def test_malformed_json_bodies_are_4xx(client: TestClient, body: str) -> None:
    r = client.post(
        "/api/runs",
        content=body.encode("utf-8", "surrogateescape"),
        headers={**OP, "content-type": "application/json"},
    )
    assert 400 <= r.status_code < 500, (r.status_code, r.text[:200])
