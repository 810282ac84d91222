"""A calibration run through the REST API, from POST to certificate."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

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
        print(cert.json()["number"])
