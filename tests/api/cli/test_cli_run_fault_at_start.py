"""``calbench run`` on a bench whose device does not answer when the run starts — a table on a
pseudo-terminal that stays silent, a Modbus TCP DAQ (pymodbus) that does not reply — behaves
as the service: the run is stored ``interrupted`` with the device, its path and the fault,
resumed automatically, and completes once the device answers; if it never does within the
tries, the command ends with exit code 4, naming the device, the fault and the ``calbench
resume`` command that continues it, and that command then completes the run as requested."""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path

import pytest

import station.execution.fault_retry as fault_retry
from api.cli import main
from api.cli.run import INTERRUPTED_EXIT
from tests.e2e.helpers import SIM_SPEED
from tests.support.pty_bench import pty_bench

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]

FAST = fault_retry.RetryPolicy(attempts=2, first_wait_s=0.1, max_wait_s=0.2)
DWELL_S = 4.0


@pytest.fixture
def env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("CALBENCH_DATABASE_URL", f"sqlite:///{tmp_path / 'calbench.db'}")
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CALBENCH_BENCH_NAME", "bench-pty")
    return tmp_path


def rows(db: Path, sql: str) -> list[tuple[object, ...]]:
    with sqlite3.connect(db) as conn:
        return conn.execute(sql).fetchall()


def test_a_table_silent_at_the_start_leaves_the_run_interrupted_and_calbench_resume_completes_it(
    env: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(fault_retry, "RetryPolicy", lambda: FAST)  # the command's default policy, faster
    with pty_bench(env, speed=SIM_SPEED) as bench:
        bench.sim.controller.inject("no_reply")
        args = ["--bench-file", str(bench.bench_file), "--dwell-s", f"{DWELL_S:g}"]
        code = main(["run", "static-12", "--unit", "SN-SILENT", *args])
        out = capsys.readouterr()
        assert code == INTERRUPTED_EXIT == 4, out
        [(run_id, state, error, dwell)] = rows(
            env / "calbench.db", "SELECT id, state, error, requested_dwell_s FROM run"
        )
        assert state == "interrupted" and dwell == DWELL_S
        assert f"the table at serial://{bench.table_path} did not answer: DeviceTimeout" in str(error)
        assert (
            f"run {run_id}: interrupted" in out.out
            and bench.table_path in out.out
            and "DeviceTimeout" in out.out
        )
        assert "nothing was recorded" in out.out
        assert out.err.count("resuming in") == FAST.attempts  # the automatic tries, each said
        command = out.out.rsplit("resume it with: ", 1)[1].split()
        assert command[:3] == ["calbench", "resume", run_id]
        audit = rows(env / "calbench.db", f"SELECT action, state FROM run_audit WHERE run_id = '{run_id}'")
        assert ("state", "interrupted") in audit

        bench.sim.controller.clear("no_reply")  # the table answers again
        code = main([*command[1:]])
        out = capsys.readouterr()
    assert code == 0, out.err
    assert f"run {run_id}: PASS" in out.out and "12 windows" in out.out
    assert f"dwell {DWELL_S:g} s given by the operator" in out.out  # started as it was requested
    [(state, resumes)] = rows(env / "calbench.db", "SELECT state, resume_count FROM run")
    assert state == "completed" and resumes == FAST.attempts + 1


def test_a_daq_silent_at_the_start_is_resumed_automatically_and_the_run_completes(
    env: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pty_bench(env, speed=SIM_SPEED) as bench:
        daq = bench.sim.daq_server
        assert daq is not None
        daq.set_silent(True)
        db = env / "calbench.db"

        def answer_once_interrupted() -> None:  # the DAQ comes back after the first failed start
            import time

            deadline = time.monotonic() + 120.0
            while time.monotonic() < deadline:
                if db.exists():
                    try:
                        if rows(db, "SELECT 1 FROM run WHERE state = 'interrupted'"):
                            break
                    except sqlite3.OperationalError:
                        pass
                time.sleep(0.05)
            daq.set_silent(False)

        helper = threading.Thread(target=answer_once_interrupted, daemon=True)
        helper.start()
        code = main(
            [
                "run",
                "static-12",
                "--unit",
                "SN-DAQ",
                "--bench-file",
                str(bench.bench_file),
                "--dwell-s",
                "4",
            ]
        )
        helper.join(timeout=5.0)
        out = capsys.readouterr()
    assert code == 0, out.err
    assert f"the DAQ at {bench.sim.daq_url} did not answer" in out.err and "resuming in 1 s (1/6)" in out.err
    [(run_id, state)] = rows(db, "SELECT id, state FROM run")
    assert state == "completed" and f"run {run_id}: PASS" in out.out
    audit = rows(db, f"SELECT action, state FROM run_audit WHERE run_id = '{run_id}' ORDER BY id")
    assert ("state", "interrupted") in audit and any(a == "resume" for a, _ in audit)
