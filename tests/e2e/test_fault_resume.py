"""A simulated bench that stalls or is killed mid-run, against real processes: the run is left
``interrupted`` (table safe, recording cut at its last durable chunk), resumed automatically
from its last complete window, and completes — through ``calbench run`` and through the
service's bench agent. Before, a 2 s stall ended the run in error for good."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.recording.reader import read_recording
from tests.e2e.helpers import RATE_HZ, SIM_SPEED, wall_budget_s
from tests.e2e.service_process import ServiceProcess, wait_for
from tests.e2e.test_service_crash import RUN_SIM_S, run_until_windows
from tests.support.sim_faults import kill, lose_line, sim_pid, stall

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]

CALBENCH = str(Path(sys.executable).with_name("calbench"))


def windows_done(db: Path) -> int:
    if not db.exists():
        return 0
    try:
        with sqlite3.connect(db) as conn:
            row = conn.execute("SELECT last_complete_window FROM run").fetchone()
    except sqlite3.OperationalError:
        return 0
    return 0 if row is None or row[0] is None else int(row[0]) + 1


def check_recording(path: str) -> None:
    """Twelve windows, time increasing, every hole in the time axis a recorded gap."""
    rec = read_recording(path)
    assert len(rec.sidecar.segments or ()) == 12
    step = np.diff(rec.t_s)
    assert np.all(step > 0)
    holes = int(np.sum(step > 1.5 / rec.sidecar.sample_rate_hz))
    gaps = rec.sidecar.extra.get("calbench_gaps", [])
    assert holes <= len(gaps), (holes, gaps)


@pytest.mark.parametrize("fault", ["stall", "kill", "lost line"])
def test_calbench_run_resumes_itself_after_the_simulator_stalls_dies_or_loses_its_line(
    tmp_path: Path, fault: str
) -> None:
    env = {
        **os.environ,
        "CALBENCH_DATA_DIR": str(tmp_path),
        "CALBENCH_DATABASE_URL": f"sqlite:///{tmp_path / 'calbench.db'}",
        "CALBENCH_SIM_SAMPLE_RATE_HZ": str(RATE_HZ),
        "CALBENCH_BENCH_NAME": "bench-fault",
    }
    cmd = [CALBENCH, "run", "static-12", "--unit", "SN-FAULT-CLI", "--sim", "--sim-speed", str(SIM_SPEED)]
    proc = subprocess.Popen(
        [*cmd, "--dwell-s", "8", "--seed", "3", "--json"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        wait_for(
            lambda: windows_done(tmp_path / "calbench.db") >= 2, wall_budget_s(RUN_SIM_S / 6), "2 windows"
        )
        pid = sim_pid(proc.pid)
        assert pid is not None
        if fault == "stall":
            stall(pid, 2.0)
        elif fault == "kill":
            kill(pid)
        else:
            lose_line(pid)
        out, err = proc.communicate(timeout=wall_budget_s(RUN_SIM_S) + 120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err[-2000:]
    body: dict[str, Any] = json.loads(out)
    assert body["outcome"] == "PASS" and body["n_windows"] == 12
    assert "device fault: " in err and "resuming in 1 s (1/6)" in err
    with sqlite3.connect(tmp_path / "calbench.db") as conn:
        ((state, resumes, error),) = conn.execute("SELECT state, resume_count, error FROM run").fetchall()
    assert state == "completed" and resumes >= 1 and error is None
    check_recording(body["recording"])


def test_the_agent_resumes_a_run_whose_simulator_stalled(tmp_path: Path) -> None:
    svc = ServiceProcess(tmp_path, SIM_SPEED)
    try:
        svc.start()
        run_id = run_until_windows(svc, 2)
        agent = svc.agent_pid()
        assert agent is not None
        pid = sim_pid(agent)
        assert pid is not None
        freezer = threading.Thread(target=stall, args=(pid, 3.0))
        freezer.start()
        freezer.join()

        def done() -> dict[str, Any] | None:
            run = svc.get(f"/api/runs/{run_id}")
            assert run["state"] in ("running", "interrupted", "queued", "completed"), run
            return run if run["state"] == "completed" and run.get("certificate_number") else None

        wait_for(done, wall_budget_s(RUN_SIM_S) + 120, f"run {run_id} to complete")
        ((resumes, error, path, auto),) = svc.sql(
            "SELECT resume_count, error, recording_path, auto_resume FROM run WHERE id = ?", run_id
        )
        assert resumes >= 1 and error is None
        assert json.loads(auto)["attempt"] >= 1
        check_recording(path)
        assert svc.agent_pid() == agent
    finally:
        svc.kill()
