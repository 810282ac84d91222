"""The bench agent's own rules: a run it owns but no longer drives is ended, not left running;
a queued run of another bench is not its business."""

from __future__ import annotations

import os
import socket
import time
from pathlib import Path

import pytest

from api.cli import main
from api.cli.agent import ALREADY_RUNNING
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Run, RunState
from db.repo.queue import queue_run
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from station.agent.bench_agent import BenchAgent
from station.execution.bench_lock import BenchLock, read_holder
from station.runs.queue import RunQueue
from station.settings import Settings
from tests.support.service_helpers import service_settings


def test_a_run_left_live_by_a_failed_write_is_ended_as_error(tmp_path: Path) -> None:
    agent = BenchAgent(service_settings(tmp_path))
    try:
        with agent.sessions.begin() as s:
            unit = get_or_create_unit(s, "SN-ORPHAN", bench_id=agent.bench_id)
            create_run(
                s,
                "orphan",
                unit.id,
                "static-12",
                bench_id=agent.bench_id,
                state=RunState.RUNNING,
                owner_pid=os.getpid(),
                owner_host=socket.gethostname(),
            )
            create_run(
                s,
                "other-owner",
                unit.id,
                "static-12",
                bench_id=agent.bench_id,
                state=RunState.RUNNING,
                owner_pid=os.getpid() + 1,
                owner_host="another-host",
            )
            other = get_or_create_bench(s, "another-bench")
            queue_run(s, "elsewhere", unit.id, other.id, "static-12", {}, kind="calibration")
        assert agent.tick() is None  # idle runner: the orphan is ended; the bench is held by the other
        with agent.sessions.begin() as s:
            orphan, held, elsewhere = (s.get(Run, i) for i in ("orphan", "other-owner", "elsewhere"))
            assert orphan is not None and orphan.state is RunState.ERROR and orphan.outcome == "ERROR"
            assert orphan.error is not None and "could not be stored" in orphan.error
            assert held is not None and held.state is RunState.RUNNING  # another process's run
            assert elsewhere is not None and elsewhere.state is RunState.QUEUED  # another bench's
    finally:
        agent.close()


def test_a_drift_check_is_queued_once_per_unit_by_several_api_processes(tmp_path: Path) -> None:
    settings = service_settings(tmp_path)
    engine = open_database(settings.effective_database_url)
    try:
        queues = [
            RunQueue(settings, make_session_factory(engine), make_session_factory(engine, read_only=True))
            for _ in range(2)
        ]  # two API processes, each with its nightly scheduler
        first = queues[0].start("SN-DRIFT", "static-12", dwell_s=3.0, kind="drift_check")
        again = queues[1].start("SN-DRIFT", "static-12", dwell_s=3.0, kind="drift_check")
        other = queues[1].start("SN-DRIFT", "static-12", dwell_s=3.0)  # an operator's calibration
        assert again.id == first.id and other.id != first.id
        assert queues[0].queued() == [first.id, other.id]
        assert queues[0].abort(first.id) and queues[0].queued() == [other.id]
        assert queues[1].start("SN-DRIFT", "static-12", dwell_s=3.0, kind="drift_check").id != first.id
    finally:
        engine.dispose()


def test_a_second_agent_for_the_bench_exits_naming_the_first(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CALBENCH_DATABASE_URL", f"sqlite:///{tmp_path / 'calbench.db'}")
    monkeypatch.setenv("CALBENCH_BENCH_NAME", "bench/one")
    path = tmp_path / "bench-bench_one.lock"
    held = BenchLock(Settings(), "calbench agent").acquire()  # the first agent
    try:
        holder = read_holder(path)
        assert holder is not None and holder.pid == os.getpid() and holder.kind == "calbench agent"
        assert main(["agent", "--sim"]) == ALREADY_RUNNING
        err = capsys.readouterr().err
        assert err.count("\n") == 1, err
        assert f"calbench agent pid {os.getpid()} on host {socket.gethostname()} since " in err
        assert "bench/one" in err
    finally:
        held.release()
    assert read_holder(path) is None


def test_a_pause_asked_while_the_run_waits_in_the_queue_holds_it_once_claimed(tmp_path: Path) -> None:
    settings = service_settings(tmp_path)
    agent = BenchAgent(settings)
    queue = RunQueue(settings, agent.sessions, agent.read_sessions)
    try:
        run = queue.start("SN-QUEUED-PAUSE", "static-12", dwell_s=3.0)
        assert queue.pause(run.id)  # nobody has claimed it yet: stored for the agent
        with agent.sessions.begin() as s:
            row = s.get(Run, run.id)
            assert row is not None and row.state is RunState.QUEUED and row.owner_pid is None
        assert agent.tick() == run.id  # claimed and started
        deadline = time.monotonic() + 60.0
        state = RunState.QUEUED
        while time.monotonic() < deadline and state is not RunState.PAUSED:
            agent.tick()  # applies the stored pause
            time.sleep(0.1)
            with agent.read_sessions.begin() as s:
                row = s.get(Run, run.id)
                assert row is not None
                state = row.state
        assert state is RunState.PAUSED
        assert queue.abort(run.id)
        agent.tick()
        assert agent.runner.wait_idle(60.0)
    finally:
        agent.close()


def test_an_embedded_service_and_a_second_run_are_refused_while_the_bench_is_driven(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CALBENCH_DATABASE_URL", f"sqlite:///{tmp_path / 'calbench.db'}")
    monkeypatch.setenv("CALBENCH_BENCH_NAME", "vm")
    monkeypatch.setenv("CALBENCH_TOKENS", "operator:operator-secret-0001")
    held = BenchLock(Settings(), "calbench run").acquire()  # e.g. a calbench run mid-run
    try:
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        assert main(["serve", "--sim", "--agent", "embedded", "--port", str(port)]) == ALREADY_RUNNING
        assert main(["resume", "some-run", "--sim"]) == ALREADY_RUNNING
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 2, lines
        who = f"is driven by calbench run pid {os.getpid()} on host {socket.gethostname()} since "
        assert lines[0].startswith("calbench serve: bench 'vm' ") and who in lines[0]
        assert lines[1].startswith("calbench resume: bench 'vm' ") and who in lines[1]
    finally:
        held.release()
