"""A unit whose model has no limits: the operator is told before the run starts, and its
certificate makes no statement of conformity and says why (never another model's limits)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from tests.support.service_helpers import OP, VIEW, service_settings, wait_final

NO_LIMITS = "no statement of conformity will be made: no limits are configured for model ADXL335"


def test_preview_and_start_warn_about_a_model_without_limits(tmp_path: Path) -> None:
    # an external agent that never comes: the run stays queued, nothing is recorded
    settings = service_settings(tmp_path, agent="external")
    with TestClient(create_app(settings, start_scheduler=False)) as client:
        for serial, model in (("SN-335", "ADXL335"), ("SN-325", "ADXL325")):
            r = client.put(f"/api/units/{serial}", json={"model": model}, headers=OP)
            assert r.status_code == 200, r.text
        preview = client.get("/api/procedures/static-12/preview?unit_serial=SN-335", headers=VIEW).json()
        assert len(preview["warnings"]) == 1 and preview["warnings"][0].startswith(NO_LIMITS), preview
        assert preview["warnings"][0].endswith("(limits are configured for: ADXL325)")
        for query in ("?unit_serial=SN-325", "?unit_serial=SN-NEW", ""):
            r = client.get(f"/api/procedures/static-12/preview{query}", headers=VIEW)
            assert r.status_code == 200 and r.json()["warnings"] == [], (query, r.text)
        r = client.post("/api/runs", json={"unit_serial": "SN-335", "procedure": "static-12"}, headers=OP)
        assert r.status_code == 202 and r.json()["warnings"][0].startswith(NO_LIMITS), r.text
        r = client.post("/api/runs", json={"unit_serial": "SN-325", "procedure": "static-12"}, headers=OP)
        assert r.status_code == 202 and r.json()["warnings"] == [], r.text
    unnamed = service_settings(tmp_path / "b", agent="external", limits_model="")
    with TestClient(create_app(unnamed, start_scheduler=False)) as client:
        r = client.get("/api/procedures/static-12/preview?unit_serial=SN-NEW", headers=VIEW)
        assert r.json()["warnings"] == [
            "no statement of conformity will be made: the unit's registration names no model and no "
            "default limits model is set"
        ]


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_model_without_limits_is_certified_without_a_statement_of_conformity(tmp_path: Path) -> None:
    with TestClient(create_app(service_settings(tmp_path), start_scheduler=False)) as client:
        r = client.put("/api/units/SN-335", json={"model": "ADXL335"}, headers=OP)
        assert r.status_code == 200, r.text
        r = client.post("/api/runs", json={"unit_serial": "SN-335", "procedure": "static-12"}, headers=OP)
        assert r.status_code == 202, r.text
        body = wait_final(client, r.json()["id"])
        assert body["state"] == "completed", body["error"]
        assert body["limit_checks"] == []  # not judged against the default model's limits
        # no PASS or FAIL anywhere the run is listed: the note says why instead
        note = "no conformity statement: no limits are configured for model ADXL335"
        assert body["outcome"] is None and body["conformity_note"] == note, body
        listed = client.get("/api/runs", headers=VIEW).json()
        history = client.get("/api/units/SN-335/history", headers=VIEW).json()["runs"]
        for row in (*listed, *history):
            assert row["outcome"] is None and row["conformity_note"] == note, row
        assert len(history) == 1 and any(row["id"] == body["id"] for row in listed)
        cert = client.get(f"/api/runs/{body['id']}/certificate", headers=VIEW)
        assert cert.status_code == 200, cert.text
        pdf_bytes = client.get(f"/api/runs/{body['id']}/certificate.pdf", headers=VIEW).content
    content = cert.json()["content"]
    assert content["item"]["model"] == "ADXL335"
    conf = content["conformity"]
    assert conf["requested"] is False and conf["checks"] == [], conf
    assert conf["statement"].startswith("No statement of conformity is made")
    assert "no limits are configured for model ADXL335" in conf["statement"]
    assert "conforms" not in conf["statement"] and "PASS" not in conf["statement"]
    assert "ADXL325" not in json.dumps(conf)  # never another model's limits, nor its name
    if shutil.which("pdftotext") is not None:  # every page of the PDF says no statement is made
        pdf = tmp_path / "c.pdf"
        pdf.write_bytes(pdf_bytes)
        text = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True).stdout
        flat = " ".join(text.split())
        assert "no limits are configured for model ADXL335" in flat
        pages = int(re.findall(r"Page \d+ of (\d+)", flat)[-1])
        assert flat.count("Conformity: no statement of conformity") == pages >= 3
        assert "conforms to" not in flat and "ADXL325" not in flat


def test_the_preview_refuses_a_serial_that_no_unit_can_have(tmp_path: Path) -> None:
    app = create_app(service_settings(tmp_path, agent="external"), start_scheduler=False)
    with TestClient(app) as client:
        r = client.get("/api/procedures/static-12/preview?unit_serial=SN%20X%E2%80%AE", headers=VIEW)
        assert r.status_code == 422, r.text


def test_an_unreadable_limits_file_is_named_before_the_run(tmp_path: Path) -> None:
    from station.certificates.conformity import conformity_warning

    bad = tmp_path / "limits.json"
    bad.write_text("{")
    warning = conformity_warning(service_settings(tmp_path, limits_file=bad), "ADXL325", "V")
    assert warning is not None and warning.startswith("the limits file cannot be read")
    assert str(bad) in warning
