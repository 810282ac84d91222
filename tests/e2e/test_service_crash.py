"""The service or its bench agent stops mid-run and the run is not lost.

``calbench serve --sim`` runs as a real subprocess on loopback with a temporary SQLite
database; it starts the bench agent as its own process. A static-12 run is started over
REST; after a few windows:

* the API process is killed (SIGKILL): the agent records on, the restarted API finds it at
  work, and the run completes as one run with no hole in its recording;
* the agent is killed (SIGKILL) or the whole service stopped (SIGTERM: a deploy restart):
  the run is ``interrupted``, its recording holds every durable chunk the database counts,
  ``POST /api/runs/{id}/resume`` finishes it on the same simulated unit.

Each time the certificate is issued and the fit agrees with the simulated truth within its
uncertainty.
"""

from __future__ import annotations

import itertools
import os
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.fitted_model import FittedModel
from bench.recording.reader import read_recording
from drivers.factory import simulated_unit
from tests.e2e.helpers import SIM_SPEED, wall_budget_s, z_scores
from tests.e2e.service_process import ServiceProcess, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]

SERIAL = "SN-SVC-STOP"
DWELL_S = 8.0
RUN_SIM_S = 12 * (DWELL_S + 15.0)
"""Simulated duration of the run: twelve windows with their moves and settling (bounded)."""


def run_until_windows(svc: ServiceProcess, n: int) -> str:
    """Start a static-12 run over REST and wait until ``n`` windows are reported complete."""
    resp = svc.post("/api/runs", {"unit_serial": SERIAL, "procedure": "static-12", "dwell_s": DWELL_S})
    assert resp.status_code == 202, resp.text
    run_id = str(resp.json()["id"])

    def enough() -> bool:
        run = svc.get(f"/api/runs/{run_id}")
        assert run["state"] in ("queued", "running"), run
        return run.get("last_complete_window") is not None and run["last_complete_window"] >= n - 1

    wait_for(enough, wall_budget_s(n * RUN_SIM_S / 12), f"{n} windows of run {run_id}")
    return run_id


def durable_recording(svc: ServiceProcess, run_id: str) -> Path:
    """Check that the recording holds every chunk the database calls durable; its path."""
    ((path,),) = svc.sql("SELECT recording_path FROM run WHERE id = ?", run_id)
    ((rows, end_byte, n_chunks),) = svc.sql(
        "SELECT max(first_sample + n_samples), max(end_byte), count(*) FROM sample_chunk WHERE run_id = ?",
        run_id,
    )
    assert n_chunks >= 1 and rows > 0
    data = Path(path).read_bytes()
    assert len(data) >= end_byte
    # The durable prefix is the header row and exactly the rows the chunks count.
    assert data[:end_byte].count(b"\n") - 1 == rows, (data[:end_byte].count(b"\n"), rows)
    return Path(path)


def resume_to_completion(svc: ServiceProcess, run_id: str) -> dict[str, Any]:
    """Resume over REST, check the refusals while it runs, wait for the certificate."""
    resp = svc.post(f"/api/runs/{run_id}/resume")
    assert resp.status_code == 202, resp.text
    body = resp.json()
    assert body["action"] == "resume" and body["resumed_from_window"] >= 3
    again = svc.post(f"/api/runs/{run_id}/resume")
    assert again.status_code == 409, again.text  # it holds the bench now: nothing to resume
    assert svc.post("/api/runs/no-such-run/resume").status_code == 404

    def done() -> dict[str, Any] | None:
        run = svc.get(f"/api/runs/{run_id}")
        if run["state"] in ("failed", "error", "aborted", "interrupted"):
            raise AssertionError(f"resumed run ended {run['state']}: {run.get('error')}")
        return run if run["state"] == "completed" and run.get("certificate_number") else None

    run: dict[str, Any] = wait_for(done, wall_budget_s(RUN_SIM_S), f"run {run_id} to complete after resume")
    return run


def check_completed(svc: ServiceProcess, run_id: str, run: dict[str, Any], path: Path) -> None:
    """One recording of twelve windows, the certificate issued, the fit on the truth."""
    rec = read_recording(path)
    labels = [s.label for s in rec.sidecar.segments or ()]
    assert labels == [f"pos{i:02d}" for i in range(1, 13)]
    assert np.all(np.diff(rec.t_s) > 0)
    assert run["n_samples"] == len(rec.t_s)
    cert = svc.get(f"/api/runs/{run_id}/certificate")
    assert cert["number"] == run["certificate_number"] and len(cert["sha256"]) == 64
    ((age,),) = svc.sql("SELECT sim_age_days FROM run WHERE id = ?", run_id)
    z = z_scores(FittedModel.from_contract(run["calibration"]), simulated_unit(SERIAL, age))
    assert np.max(np.abs(z)) < 4.5, z


def test_api_killed_mid_run_the_run_never_stops_recording(tmp_path: Path) -> None:
    """The API process dies (SIGKILL) and comes back: the agent records on, the run completes
    as one uninterrupted run, and its recording has no hole."""
    svc = ServiceProcess(tmp_path, SIM_SPEED)
    try:
        svc.start()
        run_id = run_until_windows(svc, 3)
        agent = svc.agent_pid()
        assert agent is not None and svc.proc is not None and agent != svc.proc.pid
        assert svc.stop(signal.SIGKILL) == -signal.SIGKILL
        ((before,),) = svc.sql("SELECT last_complete_window FROM run WHERE id = ?", run_id)

        def recorded_on() -> bool:  # while no API process exists
            ((now,),) = svc.sql("SELECT last_complete_window FROM run WHERE id = ?", run_id)
            return now is not None and now > before

        wait_for(recorded_on, wall_budget_s(2 * RUN_SIM_S / 12), "windows recorded while the API was down")
        svc.start()
        assert svc.agent_pid() == agent  # the new API found the agent at work and left it alone

        def done() -> dict[str, Any] | None:
            run = svc.get(f"/api/runs/{run_id}")
            assert run["state"] in ("running", "completed"), run
            return run if run["state"] == "completed" and run.get("certificate_number") else None

        run = wait_for(done, wall_budget_s(RUN_SIM_S), f"run {run_id} to complete")
        ((resumes, error),) = svc.sql("SELECT resume_count, error FROM run WHERE id = ?", run_id)
        assert resumes == 0 and error is None
        path = durable_recording(svc, run_id)
        check_completed(svc, run_id, run, path)
        rec = read_recording(path)
        step = np.diff(rec.t_s)
        assert np.max(step) < 1.5 * np.median(step), "a hole in the recording"
        chunks = svc.sql(
            "SELECT first_sample, n_samples FROM sample_chunk WHERE run_id = ? ORDER BY seq", run_id
        )
        assert all(a + n == b for (a, n), (b, _) in itertools.pairwise(chunks))
        assert svc.stop(signal.SIGTERM) == -signal.SIGTERM
        wait_for(lambda: svc.agent_pid() is None, 120, "the adopted agent to stop with the service")
    finally:
        svc.kill()


def test_agent_killed_mid_run_then_resumed(tmp_path: Path) -> None:
    """The agent dies (SIGKILL): the service starts a new one, which marks the run
    ``interrupted``; a resume over REST finishes it on the same simulated unit."""
    svc = ServiceProcess(tmp_path, SIM_SPEED)
    try:
        svc.start()
        run_id = run_until_windows(svc, 4)
        agent = svc.agent_pid()
        assert agent is not None
        os.kill(agent, signal.SIGKILL)
        wait_for(lambda: svc.agent_pid() not in (None, agent), 120, "a new agent")

        def interrupted() -> bool:
            return bool(svc.get(f"/api/runs/{run_id}")["state"] == "interrupted")

        wait_for(interrupted, 60, "the run to be marked interrupted")
        path = durable_recording(svc, run_id)
        run = resume_to_completion(svc, run_id)
        check_completed(svc, run_id, run, path)
        assert svc.stop(signal.SIGTERM) == -signal.SIGTERM
    finally:
        svc.kill()


def test_service_stopped_mid_run_then_resumed(tmp_path: Path) -> None:
    """SIGTERM to the service (a deploy restart): it stops its agent, which leaves the run
    ``interrupted`` with the table safe; after the restart a resume finishes it."""
    svc = ServiceProcess(tmp_path, SIM_SPEED)
    try:
        svc.start()
        run_id = run_until_windows(svc, 4)
        code = svc.stop(signal.SIGTERM)
        assert code == -signal.SIGTERM, svc.log()
        assert svc.agent_pid() is None
        ((state, error),) = svc.sql("SELECT state, error FROM run WHERE id = ?", run_id)
        assert state.lower() == "interrupted", (state, error, svc.log())
        assert "shut down" in error
        path = durable_recording(svc, run_id)

        svc.start()
        run = svc.get(f"/api/runs/{run_id}")
        assert run["state"] == "interrupted", run
        assert run["last_complete_window"] >= 3
        run = resume_to_completion(svc, run_id)
        check_completed(svc, run_id, run, path)
        assert svc.stop(signal.SIGTERM) == -signal.SIGTERM
    finally:
        svc.kill()
