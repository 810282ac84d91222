"""A unit registered and calibrated through the REST API, from PUT and POST to the certificate,
with its diagnosis stored."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from station.certificates.issue import findings_of
from tests.support.service_helpers import OP, VIEW, service_settings, wait_final

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]  # a whole simulated run to its certificate
NOMINAL_SCALE = 0.174 / 9.80665  # V/(m/s2): the simulated unit's 174 mV/g


def test_run_to_certificate(tmp_path: Path) -> None:
    with TestClient(create_app(service_settings(tmp_path), start_scheduler=False)) as client:
        reg = {
            "customer_name": "Acme Robotics",
            "received_on": "2025-03-04",
            "model": "ADXL325",
            "nominal_scale": NOMINAL_SCALE,
            "nominal_bias": 1.5,
        }
        r = client.put("/api/units/SN-SMOKE", json=reg, headers=OP)
        assert r.status_code == 200 and r.json()["customer_address"] is None, r.text
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
        content = cert.json()["content"]
        assert content["customer"] == {
            "name": "Acme Robotics",
            "address": "not stated",
            "source": "unit registration",
        }
        assert content["dates"]["received"] == "2025-03-04" and content["item"]["model"] == "ADXL325"
        before, after = content["g_check"]["before"], content["g_check"]["after"]
        # the nominal 174 mV/g, 1.5 V model of a unit with ~1 % scale and ~25 mg zero-g errors
        # misses |g| by far more than the fitted one does
        assert before["std_m_s2"] > 5 * after["std_m_s2"] and 1e-3 < abs(before["mean_error_m_s2"]) < 1.0
        assert "0.0177" in content["g_check"]["before_basis"]
        listed = client.get("/api/runs", headers=VIEW).json()
        assert listed[0]["diagnosis"] is None and listed[0]["n_findings"] == len(diag["findings"])
