"""``calbench serve --sim`` as a real subprocess on loopback (it starts the bench agent as its own
process, which starts the simulated bench as another), for the service's crash tests."""

from __future__ import annotations

import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx

from station.execution.bench_lock import read_holder
from tests.e2e.helpers import RATE_HZ

CALBENCH = str(Path(sys.executable).with_name("calbench"))
BENCH = "bench-service-crash"
OPERATOR = "operator-crash-0001"
VIEWER = "viewer-crash-0001"
OP = {"Authorization": f"Bearer {OPERATOR}"}
VIEW = {"Authorization": f"Bearer {VIEWER}"}


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class ServiceProcess:
    """One ``calbench serve --sim`` process on a temporary SQLite database and data directory.

    :param tmp_path: holds ``calbench.db``, the recordings and the service's log files.
    :param sim_speed: simulated seconds per wall second.
    """

    def __init__(self, tmp_path: Path, sim_speed: float) -> None:
        self.tmp_path, self.sim_speed = tmp_path, sim_speed
        self.db = tmp_path / "calbench.db"
        self.env = {
            **os.environ,
            "CALBENCH_DATABASE_URL": f"sqlite:///{self.db}",
            "CALBENCH_DATA_DIR": str(tmp_path),
            "CALBENCH_SIM_SAMPLE_RATE_HZ": str(RATE_HZ),
            "CALBENCH_BENCH_NAME": BENCH,
            "CALBENCH_TOKENS": f"operator:{OPERATOR},viewer:{VIEWER}",
            "CALBENCH_DRIFT_TIME": "",
        }
        self.proc: subprocess.Popen[bytes] | None = None
        self.base = ""
        self.n_starts = 0

    def start(self, timeout_s: float = 60.0) -> str:
        """Start the service and wait for ``/api/health``; the base URL."""
        port = free_port()
        self.n_starts += 1
        log = (self.tmp_path / f"serve-{self.n_starts}.log").open("wb")
        cmd = [
            CALBENCH,
            "serve",
            "--sim",
            "--sim-speed",
            str(self.sim_speed),
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--log-level",
            "warning",
        ]
        self.proc = subprocess.Popen(cmd, env=self.env, stdout=log, stderr=subprocess.STDOUT)
        log.close()
        self.base = f"http://127.0.0.1:{port}"
        wait_for(lambda: self._healthy(), timeout_s, f"service on {self.base} to answer")
        return self.base

    def _healthy(self) -> bool:
        assert self.proc is not None
        if self.proc.poll() is not None:
            raise AssertionError(f"calbench serve exited with {self.proc.returncode}: {self.log()}")
        try:
            return httpx.get(f"{self.base}/api/health", timeout=2.0).status_code == 200
        except httpx.TransportError:
            return False

    def log(self) -> str:
        """The output of the latest start."""
        return (self.tmp_path / f"serve-{self.n_starts}.log").read_text(errors="replace")

    def get(self, path: str) -> Any:
        resp = httpx.get(f"{self.base}{path}", headers=VIEW, timeout=30.0)
        assert resp.status_code == 200, (path, resp.status_code, resp.text)
        return resp.json()

    def post(self, path: str, body: object | None = None) -> httpx.Response:
        return httpx.post(f"{self.base}{path}", headers=OP, json=body, timeout=30.0)

    def stop(self, sig: int, timeout_s: float = 90.0) -> int:
        """Send ``sig`` and wait for the process to end; its return code."""
        assert self.proc is not None
        self.proc.send_signal(sig)
        return self.proc.wait(timeout=timeout_s)

    def agent_pid(self) -> int | None:
        """The pid of the bench's agent process (from its lock file), ``None`` if none runs."""
        holder = read_holder(self.tmp_path / f"bench-{BENCH}.lock")
        return holder.pid if holder is not None and holder.pid > 0 else None

    def kill(self) -> None:
        """End the service and its bench agent if they still run (test clean-up)."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=30)
        pid = self.agent_pid()
        if pid is not None:
            os.kill(pid, signal.SIGKILL)
            wait_for(lambda: self.agent_pid() is None, 30, f"agent {pid} to end")

    def sql(self, query: str, *args: object) -> list[tuple[Any, ...]]:
        """Rows of a query on the service's database (read directly, as an auditor would)."""
        with sqlite3.connect(self.db) as conn:
            return conn.execute(query, args).fetchall()


def wait_for(cond: Callable[[], object], timeout_s: float, what: str, poll_s: float = 0.2) -> Any:
    """Poll ``cond`` until it returns something truthy; that value.

    :raises AssertionError: not within ``timeout_s`` (a generous deadline, not a measurement).
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = cond()
        if value:
            return value
        time.sleep(poll_s)
    raise AssertionError(f"waited {timeout_s:.0f} s for {what}")
