"""GET /api/benches and the bench of POST /api/runs: named, by bench file, unknown, unable; a
killed agent's bench is offline at once."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from bench.procedures import PROCEDURES
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import RunState
from db.repo.benches import agent_alive
from db.repo.units import get_or_create_bench
from tests.support.service_helpers import OP, RATE_HZ, VIEW, service_settings

FAR_FILE = {"name": "far-table", "version": 1, "sha256": "cd" * 32, "path": "/benches/far.toml"}


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    tmp = tmp_path_factory.mktemp("benches")
    settings = service_settings(tmp)
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        engine = open_database(settings.effective_database_url)
        try:  # a second bench whose agent (elsewhere) reports static-12 only
            with make_session_factory(engine).begin() as s:
                far = get_or_create_bench(s, "bench-far").id
                agent_alive(s, far, pid=1, host="far-host", procedures=["static-12"], bench_file=FAR_FILE)
        finally:
            engine.dispose()
        yield c


def _benches(client: TestClient) -> dict[str, dict[str, Any]]:
    r = client.get("/api/benches", headers=VIEW)
    assert r.status_code == 200, r.text
    return {b["name"]: b for b in r.json()}


def test_benches_are_listed_with_what_their_agents_report(client: TestClient) -> None:
    deadline = time.monotonic() + 30
    while (own := _benches(client).get("bench-api")) is None or own["state"] != "idle":
        assert time.monotonic() < deadline, own
        time.sleep(0.2)
    # the simulated bench's three-axis table runs every registered procedure
    assert own["procedures"] == sorted(PROCEDURES)
    assert own["bench_file"]["name"] and len(own["bench_file"]["sha256"]) == 64
    assert own["running_run"] is None and own["n_queued"] == 0
    far = _benches(client)["bench-far"]
    assert (far["state"], far["agent_host"], far["procedures"]) == ("idle", "far-host", ["static-12"])
    assert client.get("/api/benches").status_code == 401


def test_a_run_named_for_a_bench_is_queued_there(client: TestClient) -> None:
    before = _benches(client)["bench-far"]["n_queued"]
    r = client.post(
        "/api/runs",
        json={"unit_serial": "SN-FAR-1", "procedure": "static-12", "bench": "bench-far"},
        headers=OP,
    )
    assert r.status_code == 202, r.text
    assert r.json()["bench"] == "bench-far" and r.json()["state"] == "queued"
    by_file = client.post(
        "/api/runs",
        json={"unit_serial": "SN-FAR-2", "procedure": "static-12", "bench": "far-table"},
        headers=OP,
    )
    assert by_file.status_code == 202 and by_file.json()["bench"] == "bench-far", by_file.text
    assert _benches(client)["bench-far"]["n_queued"] == before + 2  # nobody runs bench-far here
    run = client.get(f"/api/runs/{r.json()['id']}", headers=VIEW).json()
    assert run["state"] == "queued" and run["bench"] == "bench-far"
    for run_id in (r.json()["id"], by_file.json()["id"]):
        assert client.post(f"/api/runs/{run_id}/abort", headers=OP).json()["state"] == RunState.ABORTED.value


@pytest.mark.parametrize(
    ("bench", "procedure", "says"),
    [
        ("bench-nowhere", "static-12", "bench 'bench-nowhere' unknown; known benches: bench-api, bench-far"),
        ("bench-far", "rate-1axis", "bench 'bench-far' cannot run rate-1axis; it runs static-12"),
    ],
)
def test_an_unknown_bench_or_one_that_cannot_run_it_is_422_naming_it(
    client: TestClient, bench: str, procedure: str, says: str
) -> None:
    r = client.post(
        "/api/runs", json={"unit_serial": "SN-NONE", "procedure": procedure, "bench": bench}, headers=OP
    )
    assert r.status_code == 422, r.text
    assert says in r.text


def test_a_bench_name_with_control_characters_is_refused(client: TestClient) -> None:
    r = client.post(
        "/api/runs", json={"unit_serial": "SN-NONE", "procedure": "static-12", "bench": "a\x1bb"}, headers=OP
    )
    assert r.status_code == 422 and "bench" in r.text


def test_no_run_was_left_for_a_refused_request(client: TestClient) -> None:
    r = client.get("/api/runs?unit_serial=SN-NONE", headers=VIEW)
    assert r.status_code == 200 and r.json() == []


@pytest.mark.slow
def test_a_killed_agent_of_this_host_shows_its_bench_offline_at_once(tmp_path: Path) -> None:
    """``calbench agent --sim`` as a real process, SIGKILLed: no chance to say it stops, its record
    is fresh, yet the API on the same host shows its bench offline and sends no run there."""
    settings = service_settings(tmp_path, agent="external", bench_name="bench-api")
    env = {
        **os.environ,
        "CALBENCH_DATABASE_URL": settings.effective_database_url,
        "CALBENCH_DATA_DIR": str(tmp_path / "killed"),
        "CALBENCH_SIM_SAMPLE_RATE_HZ": str(RATE_HZ),
        "CALBENCH_BENCH_NAME": "bench-killed",
        "CALBENCH_DRIFT_TIME": "",
    }
    calbench = str(Path(sys.executable).with_name("calbench"))
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        with (tmp_path / "agent.log").open("wb") as log:  # its own session: the group is killed
            agent = subprocess.Popen(
                [calbench, "agent", "--sim", "--log-level", "warning"],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        try:
            deadline = time.monotonic() + 60
            while (killed := _benches(c).get("bench-killed")) is None or killed["state"] != "idle":
                assert agent.poll() is None, (tmp_path / "agent.log").read_text()
                assert time.monotonic() < deadline, killed
                time.sleep(0.2)
            os.killpg(agent.pid, signal.SIGKILL)
            agent.wait(timeout=30)
            killed_at = time.monotonic()
            killed = _benches(c)["bench-killed"]
            assert killed["state"] == "offline" and killed["agent_seen_at"] is not None, killed
            assert time.monotonic() - killed_at < 30.0  # well before the record went stale
            # a run left to the service does not go to it (no other bench has an agent here)
            r = c.post("/api/runs", json={"unit_serial": "SN-KILLED", "procedure": "static-12"}, headers=OP)
            assert r.status_code == 202 and r.json()["bench"] == "bench-api", r.text
        finally:
            if agent.poll() is None:
                os.killpg(agent.pid, signal.SIGKILL)
                agent.wait(timeout=30)


def test_only_operators_see_the_bench_files_path(client: TestClient) -> None:
    far = _benches(client)["bench-far"]
    assert far["bench_file"] == {k: v for k, v in FAR_FILE.items() if k != "path"}
    as_operator = {b["name"]: b for b in client.get("/api/benches", headers=OP).json()}
    assert as_operator["bench-far"]["bench_file"] == FAR_FILE
