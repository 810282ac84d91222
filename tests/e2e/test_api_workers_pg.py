"""API processes on one PostgreSQL database share nothing but the database.

- A write committed by another process reaches an open event stream of an API process through
  PostgreSQL's NOTIFY, long before the stream's poll period would have read it.
- ``calbench serve --workers 2``: a run started through one worker is followed to its end,
  events and final state with its certificate, through the other.
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from api.runs.wakeup import FALLBACK_POLL_S
from db.engine import make_engine, make_session_factory
from db.models import RunState
from db.repo.runs import finish_run, set_live_progress
from tests.db._factories import make_run
from tests.e2e.helpers import RATE_HZ, SIM_SPEED, wall_budget_s
from tests.e2e.service_process import CALBENCH, OP, OPERATOR, VIEW, VIEWER, free_port, wait_for
from tests.pg import pg_database, pg_unreachable_reason
from tests.support.sse import sse_events

pytestmark = [pytest.mark.postgres, pytest.mark.timeout(900)]

BENCH = "bench-workers"
DWELL_S = 5.0
RUN_SIM_S = 12 * (DWELL_S + 15.0)
WORKER = "x-calbench-worker"


@pytest.fixture
def pg_url() -> Iterator[str]:
    reason = pg_unreachable_reason()
    if reason:
        pytest.skip(reason)
    with pg_database() as url:
        yield url


def _env(tmp_path: Path, url: str) -> dict[str, str]:
    return {
        **os.environ,
        "CALBENCH_DATABASE_URL": url,
        "CALBENCH_DATA_DIR": str(tmp_path),
        "CALBENCH_SIM_SAMPLE_RATE_HZ": str(RATE_HZ),
        "CALBENCH_BENCH_NAME": BENCH,
        "CALBENCH_TOKENS": f"operator:{OPERATOR},viewer:{VIEWER}",
        "CALBENCH_DRIFT_TIME": "",
    }


class Serve:
    """``calbench serve ARGS`` as a subprocess on a free port (stopped with SIGTERM at the end)."""

    def __init__(self, tmp_path: Path, url: str, *args: str) -> None:
        self.port = free_port()
        self.base = f"http://127.0.0.1:{self.port}"
        self.log = tmp_path / f"serve-{self.port}.log"
        cmd = [CALBENCH, "serve", *args, "--host", "127.0.0.1", "--port", str(self.port)]
        with self.log.open("wb") as out:
            self.proc = subprocess.Popen(
                [*cmd, "--log-level", "warning"],
                env=_env(tmp_path, url),
                stdout=out,
                stderr=subprocess.STDOUT,
            )

    def health(self) -> dict[str, Any] | None:
        """``/api/health`` on a fresh connection (so a worker is picked anew), ``None`` if down."""
        if self.proc.poll() is not None:
            raise AssertionError(f"calbench serve exited: {self.log.read_text(errors='replace')}")
        try:
            r = httpx.get(f"{self.base}/api/health", timeout=5)
        except httpx.TransportError:
            return None
        return dict(r.json()) if r.status_code == 200 else None

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(120)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(30)


def _read_events(base: str, run_id: str, out: queue.Queue[tuple[str, dict[str, Any], float]]) -> None:
    """Put each ``(event, data, arrival monotonic time)`` of the run's stream into ``out``."""
    with httpx.stream("GET", f"{base}/api/runs/{run_id}/events", headers=VIEW, timeout=None) as s:
        for event, data in sse_events(s.iter_lines()):
            out.put((event, data, time.monotonic()))
            if event in ("finished", "shutdown"):
                return


def _next(events: queue.Queue[tuple[str, dict[str, Any], float]], name: str) -> tuple[dict[str, Any], float]:
    while True:
        event, data, at = events.get(timeout=60)
        if event == name:
            return data, at


def test_a_write_in_another_process_reaches_an_open_stream_at_once(tmp_path: Path, pg_url: str) -> None:
    serve = Serve(tmp_path, pg_url, "--sim", "--agent", "external")
    engine = make_engine(pg_url)
    try:
        health = wait_for(
            lambda: (h := serve.health()) is not None and h["live_updates"] == "notify" and h,
            120,
            "the API to answer and listen",
        )
        assert health["database"] == "postgresql"
        sessions = make_session_factory(engine)
        run_id = "20260101T000000Z-SN-NOTIFY-000001"
        with sessions.begin() as s:
            make_run(s, run_id, "SN-NOTIFY", bench_name=BENCH)
        events: queue.Queue[tuple[str, dict[str, Any], float]] = queue.Queue()
        reader = threading.Thread(target=_read_events, args=(serve.base, run_id, events), daemon=True)
        reader.start()
        assert _next(events, "state")[0]["state"] == "running"
        latencies = []
        for i in range(3):  # this process is the writer: the bench agent's place
            progress = {"progress": (i + 1) / 4, "state": "running"}
            writing = time.monotonic()  # from before the write: the latency includes the commit
            with sessions.begin() as s:
                set_live_progress(s, run_id, progress)
            data, at = _next(events, "progress")
            assert data == progress
            latencies.append(at - writing)
        writing = time.monotonic()
        with sessions.begin() as s:
            finish_run(s, run_id, RunState.COMPLETED, outcome="PASS")
        data, at = _next(events, "finished")
        latencies.append(at - writing)
        assert data["state"] == "completed" and data["outcome"] == "PASS"
        reader.join(30)
        # Without the notification each event would wait for the next read, up to FALLBACK_POLL_S
        # (10 s) after the previous one; a quarter of it is a wide margin for a loaded machine.
        print(f"notify latencies (s): {[round(x, 3) for x in latencies]}, poll period {FALLBACK_POLL_S} s")
        assert max(latencies) < FALLBACK_POLL_S / 4, latencies
    finally:
        serve.stop()
        engine.dispose()


def _answered_by_other(send: Any, other_than: str, what: str, attempts: int = 200) -> httpx.Response:
    """``send()`` (a request on a fresh connection) until a worker other than ``other_than`` answers."""
    for _ in range(attempts):
        r: httpx.Response = send()
        if r.headers.get(WORKER) != other_than:
            return r
        r.close()
    raise AssertionError(f"{attempts} tries of {what} all answered by worker {other_than}")


@pytest.mark.slow
def test_a_run_started_on_one_worker_is_followed_to_its_end_on_the_other(tmp_path: Path, pg_url: str) -> None:
    serve = Serve(tmp_path, pg_url, "--sim", "--sim-speed", str(SIM_SPEED), "--workers", "2")
    try:
        wait_for(lambda: serve.health(), 180, "the API workers to answer")
        workers: set[str] = set()
        for _ in range(200):  # fresh connections: the kernel hands them to either worker
            h = serve.health()
            assert h is not None and h["live_updates"] == "notify", h
            workers.add(h["worker"])
            if len(workers) == 2:
                break
        assert len(workers) == 2, workers

        r = httpx.post(
            f"{serve.base}/api/runs",
            json={"unit_serial": "SN-WORKERS", "procedure": "static-12", "dwell_s": DWELL_S},
            headers=OP,
            timeout=30,
        )
        assert r.status_code == 202, r.text
        run_id, starter = r.json()["id"], r.headers[WORKER]

        client = httpx.Client(timeout=None)

        def open_stream() -> httpx.Response:
            req = client.build_request(
                "GET", f"{serve.base}/api/runs/{run_id}/events", headers={**VIEW, "Connection": "close"}
            )
            return client.send(req, stream=True)

        stream = _answered_by_other(open_stream, starter, "the event stream")
        events: list[tuple[str, dict[str, Any]]] = []
        deadline = time.monotonic() + wall_budget_s(RUN_SIM_S)
        try:
            for event, data in sse_events(stream.iter_lines()):
                events.append((event, data))
                if event in ("finished", "shutdown"):
                    break
                assert time.monotonic() < deadline, events[-3:]
        finally:
            stream.close()
            client.close()
        names = [e for e, _ in events]
        assert names[-1] == "finished" and events[-1][1]["state"] == "completed", events[-3:]
        assert names.count("window") >= 10  # a stream opened after the start does not replay the past
        assert "progress" in names
        assert events[-1][1].get("certificate_number")

        final = _answered_by_other(
            lambda: httpx.get(
                f"{serve.base}/api/runs/{run_id}", headers={**VIEW, "Connection": "close"}, timeout=30
            ),
            starter,
            "GET /api/runs/{id}",
        )
        run = final.json()
        assert run["state"] == "completed" and run["outcome"] == "PASS", run
        assert run["certificate_number"] == events[-1][1]["certificate_number"]
        assert run["last_complete_window"] == 11
    finally:
        serve.stop()
    assert serve.proc.returncode == 0, serve.log.read_text(errors="replace")
