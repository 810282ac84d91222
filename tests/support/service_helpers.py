"""Shared pieces of the service tests: settings on a temporary directory, tokens, a movable clock."""

from __future__ import annotations

import datetime as dt
import time
from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient

from station.settings import Settings

OPERATOR = "operator-secret-0001"
VIEWER = "viewer-secret-0001"
OP = {"Authorization": f"Bearer {OPERATOR}"}
VIEW = {"Authorization": f"Bearer {VIEWER}"}
SIM_SPEED = 10.0
RATE_HZ = 100.0


def service_settings(tmp_path: Path, **overrides: Any) -> Settings:
    """Settings of a simulated bench on SQLite in ``tmp_path`` with one operator and one viewer token."""
    values: dict[str, Any] = {
        "data_dir": tmp_path,
        "database_url": f"sqlite:///{tmp_path / 'calbench.db'}",
        "tokens": [f"operator:{OPERATOR}", f"viewer:{VIEWER}"],
        "sim": True,
        "sim_speed": SIM_SPEED,
        "sim_sample_rate_hz": RATE_HZ,
        "bench_name": "bench-api",
        "run_dwell_s": 3.0,
        "drift_time": "",
        "drift_dwell_s": 3.0,
        "upload_workers": 0,  # uploads in a thread: no worker process per test app on 2 cores
    }
    values.update(overrides)
    return Settings(**values)


class MovableClock:
    """A wall clock the test moves forward (aware UTC)."""

    def __init__(self) -> None:
        self.offset = dt.timedelta(0)

    def __call__(self) -> dt.datetime:
        return dt.datetime.now(dt.UTC) + self.offset

    def advance(self, days: float) -> None:
        self.offset += dt.timedelta(days=days)


def wait_final(client: TestClient, run_id: str, timeout_s: float = 240.0) -> dict[str, Any]:
    """Poll ``GET /api/runs/{id}`` until the run is final and its results are stored."""
    deadline = time.monotonic() + timeout_s
    services = client.app.state.services  # type: ignore[attr-defined]
    while time.monotonic() < deadline:
        body = client.get(f"/api/runs/{run_id}", headers=VIEW).json()
        final = body.get("state") in ("completed", "failed", "error", "aborted")
        cur = services.runner.current  # the run holding the bench, or still storing its results
        if final and (cur is None or cur.id != run_id):  # results stored: read them
            return client.get(f"/api/runs/{run_id}", headers=VIEW).json()
        time.sleep(0.2)
    raise AssertionError(f"run {run_id} did not finish within {timeout_s} s: {body}")


def signed_link(client: TestClient, path: str, headers: dict[str, str] | None = None) -> str:
    """A signed link to ``path`` (``POST /api/links``), made with the operator token by default."""
    r = client.post("/api/links", json={"path": path}, headers=headers or OP)
    assert r.status_code == 201, r.text
    url: str = r.json()["url"]
    assert OPERATOR not in url and VIEWER not in url
    return url


def wait_state(client: TestClient, run_id: str, state: str, timeout_s: float = 120.0) -> dict[str, Any]:
    """Poll ``GET /api/runs/{id}`` until the run is in ``state`` (the bench's agent claims
    queued runs within a poll interval); the run."""
    deadline = time.monotonic() + timeout_s
    body: dict[str, Any] = {}
    while time.monotonic() < deadline:
        body = client.get(f"/api/runs/{run_id}", headers=VIEW).json()
        if body.get("state") == state:
            return body
        time.sleep(0.1)
    raise AssertionError(f"run {run_id} not {state} within {timeout_s} s: {body}")
