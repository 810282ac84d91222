"""Crash and resume: ``calbench run`` is killed with SIGKILL mid-window, ``calbench resume`` finishes it.

The run is a real subprocess on the simulated bench; its database is a temporary SQLite
file. After the kill, ``calbench runs --json`` shows the run interrupted, nothing before the
last durable chunk is lost, and the resumed run's fit agrees with an uninterrupted run of
the same simulated unit within their combined uncertainty.
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from bench.fitted_model import FittedModel
from bench.recording.reader import read_recording
from bench.run_state import Outcome
from drivers.sim.physics import SensorTruth
from station.execution.session import start_run
from tests.e2e.helpers import RATE_HZ, SIM_SPEED, difference_z, settings_for, wall_budget_s, z_scores

pytestmark = pytest.mark.slow
SEED = 11
CALBENCH = str(Path(sys.executable).with_name("calbench"))


RUN_SIM_S = 12 * (8.0 + 15.0)
"""Simulated duration of the run: twelve 8 s windows with their moves and settling (bounded)."""


def calbench(
    *args: str, env: dict[str, str], timeout_s: float = wall_budget_s(RUN_SIM_S)
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [CALBENCH, *args], env=env, capture_output=True, text=True, timeout=timeout_s, check=False
    )


def wait_for_windows(db: Path, n: int, proc: subprocess.Popen[str]) -> str:
    timeout_s = wall_budget_s(n * RUN_SIM_S / 12)
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
        if db.exists():
            try:
                with sqlite3.connect(db) as conn:
                    row = conn.execute("SELECT id, last_complete_window FROM run").fetchone()
            except sqlite3.OperationalError:
                row = None
            if row and row[1] is not None and row[1] >= n - 1:
                return str(row[0])
        time.sleep(0.05)
    raise AssertionError(f"run did not complete {n} windows in {timeout_s} s")


def test_sigkill_mid_window_then_resume(tmp_path: Path) -> None:
    db = tmp_path / "calbench.db"
    env = {
        **os.environ,
        "CALBENCH_DATABASE_URL": f"sqlite:///{db}",
        "CALBENCH_DATA_DIR": str(tmp_path),
        "CALBENCH_SIM_SAMPLE_RATE_HZ": str(RATE_HZ),
        "CALBENCH_BENCH_NAME": "bench-crash",
    }
    cmd = [
        CALBENCH,
        "run",
        "static-12",
        "--unit",
        "SN-CRASH",
        "--sim",
        "--sim-speed",
        str(SIM_SPEED),
        "--seed",
        str(SEED),
        "--dwell-s",
        "8",
        "--json",
    ]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        run_id = wait_for_windows(db, 5, proc)
        time.sleep(0.1)  # into the next move / window
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
        if proc.stdout:
            proc.stdout.close()
        if proc.stderr:
            proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    with sqlite3.connect(db) as conn:
        last_window, path = conn.execute("SELECT last_complete_window, recording_path FROM run").fetchone()
        durable_rows, durable_bytes = conn.execute(
            "SELECT max(first_sample + n_samples), max(end_byte) FROM sample_chunk"
        ).fetchone()
    assert last_window >= 4
    # Nothing before the last durable chunk is lost: the file holds at least those rows and bytes.
    assert Path(path).stat().st_size >= durable_bytes
    with Path(path).open("rb") as f:
        assert f.read().count(b"\n") - 1 >= durable_rows

    runs = calbench("runs", "--json", env=env)
    assert runs.returncode == 0, runs.stderr
    (listed,) = json.loads(runs.stdout)
    assert listed["id"] == run_id and listed["state"] == "interrupted"

    resumed = calbench("resume", run_id, "--sim", "--sim-speed", str(SIM_SPEED), "--json", env=env)
    assert resumed.returncode == 0, resumed.stderr
    out = json.loads(resumed.stdout)
    assert out["outcome"] == "PASS" and out["n_windows"] == 12
    rec = read_recording(path)
    labels = [s.label for s in rec.sidecar.segments or ()]
    assert labels == [f"pos{i:02d}" for i in range(1, 13)]
    assert np.all(np.diff(rec.t_s) > 0)
    after = json.loads(calbench("runs", "--json", env=env).stdout)[0]
    assert after["state"] == "completed"

    # An uninterrupted run of the same unit: the two fits agree within their uncertainty,
    # and both agree with the truth.
    clean = start_run(
        settings_for(tmp_path / "clean"),
        "static-12",
        "SN-CRASH",
        sim=True,
        sim_speed=SIM_SPEED,
        seed=SEED,
        dwell_s=8.0,
    )
    assert clean.outcome is Outcome.PASS and clean.calibration is not None
    stored = FittedModel.from_contract(out["calibration"], "calbench runs --json")
    dz = difference_z(stored, clean.calibration.fitted_model())
    assert np.max(np.abs(dz)) < 4.5, dz
    assert np.max(np.abs(z_scores(stored, SensorTruth.typical("V", SEED)))) < 4.5
