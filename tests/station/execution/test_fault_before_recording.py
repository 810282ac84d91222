"""A device fault before the first window: the bench does not answer when a queued run starts
(its devices do not open). The run is left ``interrupted`` as for a fault mid-run, resumed
automatically once the bench answers, and completes, instead of ending in error for good."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

import station.execution.session as session_mod
from api.main import create_app
from drivers.errors import LinkLost
from tests.support.service_helpers import OP, VIEW, service_settings, wait_final

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]


def test_a_run_whose_devices_do_not_open_at_its_start_is_resumed_and_completes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real = session_mod.open_devices
    opened: list[str] = []

    def daq_down_at_first(*args: Any, **kwargs: Any) -> Any:
        if not opened:
            opened.append("refused")
            raise LinkLost("DAQ modbus-tcp://127.0.0.1:1 unit 1: connection refused or unreachable")
        opened.append("opened")
        return real(*args, **kwargs)

    monkeypatch.setattr(session_mod, "open_devices", daq_down_at_first)
    with TestClient(create_app(service_settings(tmp_path), start_scheduler=False)) as client:
        r = client.post("/api/runs", json={"unit_serial": "SN-EARLY", "procedure": "static-12"}, headers=OP)
        assert r.status_code == 202, r.text
        body = wait_final(client, r.json()["id"], timeout_s=400.0)
        audit = client.get(f"/api/runs/{body['id']}", headers=VIEW).json()["audit"]
    assert body["state"] == "completed" and body["certificate_number"], body
    assert opened == ["refused", "opened"]
    interrupted = [a for a in audit if a["action"] == "state" and a["state"] == "interrupted"]
    assert len(interrupted) == 1 and "the devices did not open: LinkLost" in interrupted[0]["detail"]
    assert any(a["action"] == "resume" for a in audit)
