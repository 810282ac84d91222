"""Two bench agents (two simulated benches) and two API processes on one PostgreSQL database.

Each agent is ``calbench agent --sim`` as its own process (with its simulated bench in yet
another); each API is ``calbench serve --agent external`` and never touches a bench. Both
agents report to ``GET /api/benches``; runs requested through one API naming each bench
(``POST /api/runs`` ``bench``) complete on those benches with their certificates and fits on the
simulated truth; a third run named for a busy bench is queued and runs after; an unknown bench
is refused naming it; either API process shows every run, including the other bench's, live
through its event stream.
"""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from bench.fitted_model import FittedModel
from drivers.factory import simulated_unit
from tests.e2e.helpers import RATE_HZ, SIM_SPEED, wall_budget_s, z_scores
from tests.e2e.service_process import CALBENCH, OP, OPERATOR, VIEW, VIEWER, free_port, wait_for
from tests.pg import pg_database, pg_unreachable_reason
from tests.support.sse import sse_events

pytestmark = [pytest.mark.slow, pytest.mark.postgres, pytest.mark.timeout(900)]

DWELL_S = 5.0
RUN_SIM_S = 12 * (DWELL_S + 15.0)


def _env(tmp_path: Path, url: str, bench: str) -> dict[str, str]:
    return {
        **os.environ,
        "CALBENCH_DATABASE_URL": url,
        "CALBENCH_DATA_DIR": str(tmp_path / bench),
        "CALBENCH_SIM_SAMPLE_RATE_HZ": str(RATE_HZ),
        "CALBENCH_BENCH_NAME": bench,
        "CALBENCH_TOKENS": f"operator:{OPERATOR},viewer:{VIEWER}",
        "CALBENCH_DRIFT_TIME": "",
    }


def _start(cmd: list[str], env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    with log.open("wb") as out:
        return subprocess.Popen(cmd, env=env, stdout=out, stderr=subprocess.STDOUT)


def _finished(base: str, run_id: str) -> dict[str, Any] | None:
    run: dict[str, Any] = httpx.get(f"{base}/api/runs/{run_id}", headers=VIEW, timeout=30).json()
    assert run["state"] not in ("failed", "error", "aborted", "interrupted"), run
    return run if run["state"] == "completed" and run.get("certificate_number") else None


def _events(base: str, run_id: str) -> list[tuple[str, dict[str, Any]]]:
    with httpx.stream("GET", f"{base}/api/runs/{run_id}/events", headers=VIEW, timeout=None) as s:
        return list(sse_events(s.iter_lines()))


def _idle_benches(base: str) -> set[str]:
    benches = httpx.get(f"{base}/api/benches", headers=VIEW, timeout=30).json()
    return {b["name"] for b in benches if b["state"] == "idle" and "static-12" in b["procedures"]}


def test_two_agents_two_apis_one_postgresql(tmp_path: Path) -> None:
    reason = pg_unreachable_reason()
    if reason:
        pytest.skip(reason)
    procs: list[subprocess.Popen[bytes]] = []
    try:
        with pg_database() as url:
            bases: dict[str, str] = {}
            for bench in ("bench-a", "bench-b"):
                env = _env(tmp_path, url, bench)
                (tmp_path / bench).mkdir()
                agent = [CALBENCH, "agent", "--sim", "--sim-speed", str(SIM_SPEED), "--log-level", "warning"]
                procs.append(_start(agent, env, tmp_path / f"agent-{bench}.log"))
                port = free_port()
                api = [
                    CALBENCH,
                    "serve",
                    "--agent",
                    "external",
                    "--sim",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    str(port),
                    "--log-level",
                    "warning",
                ]
                procs.append(_start(api, env, tmp_path / f"api-{bench}.log"))
                bases[bench] = f"http://127.0.0.1:{port}"

            def healthy(base: str) -> bool:
                try:
                    return httpx.get(f"{base}/api/health", timeout=2).status_code == 200
                except httpx.TransportError:
                    return False

            for base in bases.values():
                wait_for(lambda b=base: healthy(b), 120, f"{base} to answer")  # type: ignore[misc]
            wait_for(
                lambda: _idle_benches(bases["bench-b"]) >= {"bench-a", "bench-b"},
                120,
                "both agents to report their benches idle",
            )
            api = bases["bench-a"]  # one API queues on both benches
            body = {"procedure": "static-12", "dwell_s": DWELL_S}
            unknown = httpx.post(
                api + "/api/runs", json={**body, "unit_serial": "SN-X", "bench": "bench-z"}, headers=OP
            )
            assert unknown.status_code == 422 and "bench 'bench-z' unknown" in unknown.text, unknown.text
            ids: dict[str, str] = {}
            for bench, serial in (("bench-b", "SN-PG-B"), ("bench-a", "SN-PG-A")):
                r = httpx.post(
                    f"{api}/api/runs", json={**body, "unit_serial": serial, "bench": bench}, headers=OP
                )
                assert r.status_code == 202 and r.json()["bench"] == bench, r.text
                ids[bench] = r.json()["id"]
            third = httpx.post(
                f"{api}/api/runs", json={**body, "unit_serial": "SN-PG-C", "bench": "bench-a"}, headers=OP
            )
            assert third.status_code == 202 and third.json()["state"] == "queued", third.text
            third_id = third.json()["id"]

            # The bench-b API follows bench-a's run live: the database is the only path.
            events = _events(bases["bench-b"], ids["bench-a"])
            assert events[-1][0] == "finished" and events[-1][1]["state"] == "completed", events[-3:]
            assert sum(1 for e, _ in events if e == "window") >= 10
            runs = {}
            for bench, run_id in ids.items():
                runs[run_id] = wait_for(
                    lambda b=bench, r=run_id: _finished(bases[b], r),  # type: ignore[misc]
                    wall_budget_s(RUN_SIM_S),
                    f"run {run_id}",
                )
            started_third = httpx.get(f"{bases['bench-b']}/api/runs/{third_id}", headers=VIEW).json()
            assert started_third["state"] in ("queued", "running", "completed")
            runs[third_id] = wait_for(
                lambda: _finished(bases["bench-a"], third_id), wall_budget_s(RUN_SIM_S), f"run {third_id}"
            )
            assert [runs[ids[b]]["bench"] for b in ids] == list(ids)
            assert runs[third_id]["bench"] == "bench-a"
            a_first, a_third = runs[ids["bench-a"]], runs[third_id]
            assert a_third["started_at"] >= a_first["finished_at"]  # queued, then run after
            listed = httpx.get(f"{bases['bench-b']}/api/runs", headers=VIEW).json()
            assert {r["id"] for r in listed} >= {*ids.values(), third_id}
            for run_id, serial in (
                (ids["bench-a"], "SN-PG-A"),
                (ids["bench-b"], "SN-PG-B"),
                (third_id, "SN-PG-C"),
            ):
                run = runs[run_id]
                assert run["unit_serial"] == serial and run["certificate_number"]
                z = z_scores(FittedModel.from_contract(run["calibration"]), simulated_unit(serial, 0.0))
                assert np.max(np.abs(z)) < 4.5, (run_id, z)
            numbers = {runs[r]["certificate_number"] for r in runs}
            assert len(numbers) == 3
            for p in procs:
                p.send_signal(signal.SIGTERM)
            for p in procs:
                p.wait(120)
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait(30)
