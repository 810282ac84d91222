"""One owner per bench, against real processes: while ``calbench serve --sim``'s agent records a
run, every other process that would drive the table, or serve on its port, is refused with one
line and a non-zero exit, and the live run completes untouched (no resume, no error, no hole).

The intruders: ``calbench run`` on the service's data directory; a second ``calbench serve`` on
the taken port; a second ``calbench serve`` on another port, stopped with SIGTERM (it must not
stop the first service's agent); a second ``calbench agent`` for the bench name from another
data directory on the same database (the database lease refuses it).
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from bench.recording.reader import read_recording
from tests.e2e.helpers import SIM_SPEED, wall_budget_s
from tests.e2e.service_process import BENCH, CALBENCH, ServiceProcess, free_port, wait_for
from tests.e2e.test_service_crash import RUN_SIM_S, run_until_windows

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]


def refused(cmd: list[str], env: dict[str, str], timeout_s: float = 60.0) -> tuple[int, str]:
    """Run an intruding command to its end; its exit code and its stderr."""
    done = subprocess.run(cmd, env=env, capture_output=True, timeout=timeout_s, text=True)
    return done.returncode, done.stderr


def one_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    return lines[0]


def test_intruders_are_refused_and_the_live_run_completes_untouched(tmp_path: Path) -> None:
    svc = ServiceProcess(tmp_path, SIM_SPEED)
    try:
        svc.start()
        run_id = run_until_windows(svc, 2)
        agent = svc.agent_pid()
        assert agent is not None
        here = socket.gethostname()

        # calbench run on the data directory the agent drives
        code, err = refused([CALBENCH, "run", "static-12", "--unit", "SN-B", "--sim"], svc.env)
        line = one_line(err)
        assert code == 3, err
        assert f"is driven by calbench agent pid {agent} on host {here} since " in line and BENCH in line

        # a second service on the taken port: exits at once, before it starts an agent
        port = int(svc.base.rsplit(":", 1)[1])
        code, err = refused([CALBENCH, "serve", "--sim", "--port", str(port)], svc.env, timeout_s=30)
        assert code == 2 and "address already in use" in one_line(err), err

        # a second service on another port: leaves the agent alone while it runs and when it stops
        other_port = free_port()
        other = subprocess.Popen(
            [CALBENCH, "serve", "--sim", "--port", str(other_port), "--log-level", "warning"],
            env=svc.env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )

        def answers() -> bool:
            assert other.poll() is None, other.returncode
            try:
                return httpx.get(f"http://127.0.0.1:{other_port}/api/health", timeout=2).status_code == 200
            except httpx.TransportError:
                return False

        wait_for(answers, 60, "the second service to answer")
        assert svc.agent_pid() == agent
        other.send_signal(signal.SIGTERM)
        assert other.wait(timeout=60) == -signal.SIGTERM
        assert svc.agent_pid() == agent

        # a second agent for the bench name, with its own data directory on the same database
        elsewhere = tmp_path / "elsewhere"
        code, err = refused(
            [CALBENCH, "agent", "--sim"], {**svc.env, "CALBENCH_DATA_DIR": str(elsewhere)}, timeout_s=60
        )
        line = one_line(err)
        assert code == 3, err
        assert f"is driven by calbench agent pid {agent} on host {here}" in line and "database lease" in line

        def done() -> dict[str, Any] | None:
            run = svc.get(f"/api/runs/{run_id}")
            assert run["state"] in ("running", "completed"), run
            return run if run["state"] == "completed" and run.get("certificate_number") else None

        wait_for(done, wall_budget_s(RUN_SIM_S), f"run {run_id} to complete")
        assert svc.agent_pid() == agent
        ((resumes, error, path),) = svc.sql(
            "SELECT resume_count, error, recording_path FROM run WHERE id = ?", run_id
        )
        assert resumes == 0 and error is None
        step = np.diff(read_recording(path).t_s)
        assert np.max(step) < 1.5 * np.median(step), "a hole in the recording"
        assert svc.sql("SELECT count(*) FROM run") == [(1,)]  # the refused run left no row
        assert not (elsewhere / "recordings").exists() or not os.listdir(elsewhere / "recordings")
    finally:
        svc.kill()
