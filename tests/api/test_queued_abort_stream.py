"""The event stream of a queued run aborted before any agent claimed it ends at once with its
``finished`` event (the abort stores it), not when the run would be considered stale."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from db.repo.recovery import DEFAULT_STALE_AFTER_S
from tests.support.service_helpers import OP, VIEW, service_settings
from tests.support.sse import sse_events

pytestmark = pytest.mark.timeout(60)


def test_an_aborted_queued_run_streams_its_end_at_once(tmp_path: Path) -> None:
    # no agent: the run stays queued until the abort
    app = create_app(service_settings(tmp_path, agent="external"), start_scheduler=False)
    with TestClient(app) as client:
        r = client.post("/api/runs", json={"unit_serial": "SN-QAB", "procedure": "static-12"}, headers=OP)
        assert r.status_code == 202, r.text
        run_id = r.json()["id"]
        assert client.get(f"/api/runs/{run_id}", headers=VIEW).json()["state"] == "queued"
        assert client.post(f"/api/runs/{run_id}/abort", headers=OP).status_code == 200

        t0 = time.monotonic()
        with client.stream("GET", f"/api/runs/{run_id}/events", headers=VIEW) as s:
            assert s.status_code == 200
            events = list(sse_events(s.iter_lines()))
        elapsed_s = time.monotonic() - t0

    assert elapsed_s < 10.0 < DEFAULT_STALE_AFTER_S
    names = [name for name, _ in events]
    assert names == ["state", "finished"], events
    finished = events[-1][1]
    assert finished["state"] == "aborted" and finished["outcome"] == "ABORTED"
    assert "before it started" in finished["error"]
