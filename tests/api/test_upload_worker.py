"""POST /api/recordings does its work off the event loop: the service answers while an upload
is being analysed, and a dead worker is a clear 503, not a hang."""

from __future__ import annotations

import asyncio
import concurrent.futures.process
import os
import threading
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from station import analysis_worker
from station.analysis_worker import AnalysisPool
from tests.conftest import EXAMPLES, STATIC_EXAMPLE
from tests.support.service_helpers import OP, service_settings

pytestmark = pytest.mark.timeout(300)


def _files() -> dict[str, tuple[str, bytes]]:
    return {
        "recording": (f"{STATIC_EXAMPLE}.csv", (EXAMPLES / f"{STATIC_EXAMPLE}.csv").read_bytes()),
        "sidecar": (f"{STATIC_EXAMPLE}.json", (EXAMPLES / f"{STATIC_EXAMPLE}.json").read_bytes()),
    }


def test_health_answers_while_an_upload_is_analysed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    release, entered = threading.Event(), threading.Event()
    real = analysis_worker.analyse_upload

    def held(csv_path: str) -> Any:
        entered.set()
        assert release.wait(60), "the test never released the analysis"
        return real(csv_path)

    monkeypatch.setattr(analysis_worker, "analyse_upload", held)
    settings = service_settings(tmp_path, upload_workers=0)
    with TestClient(create_app(settings, start_scheduler=False)) as client:
        result: dict[str, Any] = {}
        upload = threading.Thread(
            target=lambda: result.update(r=client.post("/api/recordings", files=_files(), headers=OP))
        )
        upload.start()
        assert entered.wait(60), "the analysis never started"
        # The analysis is held; were it on the event loop, this request could not be answered.
        assert client.get("/api/health").status_code == 200
        assert upload.is_alive() and "r" not in result
        release.set()
        upload.join(120)
        assert result["r"].status_code == 200, result["r"].text
        assert result["r"].json()["calibration"]["scale_matrix"]


def _exit_worker(csv_path: str) -> Any:
    os._exit(3)  # the worker process dies (killed, out of memory)


def test_a_dead_worker_is_reported_and_replaced(tmp_path: Path) -> None:
    pool = AnalysisPool(1)
    try:
        loop = asyncio.new_event_loop()
        try:
            executor = pool._executor()
            with pytest.raises(concurrent.futures.process.BrokenProcessPool):
                loop.run_until_complete(loop.run_in_executor(executor, _exit_worker, "x"))
            with pytest.raises(RuntimeError, match="worker died"):
                loop.run_until_complete(pool.analyse(EXAMPLES / f"{STATIC_EXAMPLE}.csv"))
            cal, _diag, _note = loop.run_until_complete(pool.analyse(EXAMPLES / f"{STATIC_EXAMPLE}.csv"))
        finally:
            loop.close()
        assert len(cal["bias"]) == 3
    finally:
        pool.close()


OWNER = """
import time
from station.analysis_worker import AnalysisPool
pool = AnalysisPool(1)
pool.warm()
ex = pool._executor()
deadline = time.monotonic() + 120
while not ex._processes and time.monotonic() < deadline:
    time.sleep(0.1)
print(*ex._processes, flush=True)
time.sleep(600)
"""


def test_workers_end_with_a_killed_server() -> None:
    """A server killed with SIGKILL never stops its pool: the workers notice and end."""
    import signal
    import subprocess
    import sys
    import time

    repo = Path(__file__).resolve().parents[2]
    owner = subprocess.Popen([sys.executable, "-c", OWNER], cwd=repo, stdout=subprocess.PIPE, text=True)
    try:
        assert owner.stdout is not None
        workers = [int(p) for p in owner.stdout.readline().split()]
        assert workers and all(_alive(p) for p in workers)
        owner.send_signal(signal.SIGKILL)
        owner.wait(30)
        deadline = time.monotonic() + 60
        while any(_alive(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not any(_alive(p) for p in workers), f"workers {workers} outlived the server"
    finally:
        if owner.poll() is None:
            owner.kill()


def _alive(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "\nState:\tZ" not in status
