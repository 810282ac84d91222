"""A calibration run through the REST API, from POST to certificate, with its diagnosis stored."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.certificates.issue import findings_of
from api.main import create_app
from tests.api.service_helpers import OP, VIEW, service_settings, wait_final

pytestmark = pytest.mark.timeout(300)


def test_run_to_certificate(tmp_path: Path) -> None:
    with TestClient(create_app(service_settings(tmp_path), start_scheduler=False)) as client:
        r = client.post("/api/runs", json={"unit_serial": "SN-SMOKE", "procedure": "static-12"}, headers=OP)
        assert r.status_code == 202, r.text
        run_id = r.json()["id"]
        body = wait_final(client, run_id)
        assert body["state"] == "completed", (body["error"], body)
        cert = client.get(f"/api/runs/{run_id}/certificate", headers=VIEW)
        assert cert.status_code == 200, cert.text
        diag = body["diagnosis"]
        assert diag is not None, body["diagnosis_note"]
        for key in ("unit", "baseline", "mismatch", "findings", "final"):  # the diagnose --json shape
            assert key in diag, key
        assert diag["unit"] == "SN-SMOKE" and body["n_findings"] == len(diag["findings"])
        services = client.app.state.services  # type: ignore[attr-defined]
        with services.read_sessions.begin() as s:
            stored = findings_of(s, run_id)
        assert [f["effect"] for f in stored] == [f["effect"] for f in diag["findings"]]
        certified = cert.json()["content"]["diagnosis"]
        assert certified["performed"] is True
        assert [f["effect"] for f in certified["findings"]] == [f["effect"] for f in diag["findings"]]
        listed = client.get("/api/runs", headers=VIEW).json()
        assert listed[0]["diagnosis"] is None and listed[0]["n_findings"] == len(diag["findings"])
