"""The simulated bench in its own process: the real drivers reach it over loopback, it measures
the physics as the in-process one does, it refuses bad arguments with the SimBench's message,
and it never outlives the process that owns it."""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from drivers.factory import open_bench
from drivers.sim.process import SimBenchProcess
from tests.drivers.test_sim_bench import TRUTH, assert_mean_is, drain

pytestmark = pytest.mark.timeout(180)

REPO = Path(__file__).resolve().parents[2]


def _alive(pid: int) -> bool:
    """The process exists and is not a zombie waiting to be reaped."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False
    return "\nState:\tZ" not in status


def test_process_bench_measures_the_physics_over_loopback() -> None:
    devices = open_bench("sim://?speed=10&rate=200&seed=1", truth=TRUTH, sim_process=True)
    try:
        sim = devices.sim
        assert isinstance(sim, SimBenchProcess)
        assert sim.pid is not None and sim.pid != os.getpid() and _alive(sim.pid)
        assert sim.table_url.startswith("socket://127.0.0.1:") and sim.daq_url.startswith("modbus-tcp://")
        assert sim.channel_unit == "V" and sim.sample_rate_hz == 200.0 and sim.g_local_m_s2 > 9.7
        np.testing.assert_array_equal(sim.geometry.axes, [[0, 0, 1], [1, 0, 0], [0, 0, 1]])
        devices.table.prepare()  # type: ignore[attr-defined]
        devices.daq.start()
        blocks = drain(devices.daq, 400)
        for prev, nxt in itertools.pairwise(blocks):
            assert nxt.first_seq == prev.first_seq + prev.n
        accel = np.concatenate([b.accel for b in blocks])
        assert_mean_is(accel, np.array([0.0, 0.0, sim.g_local_m_s2]))
        pid = sim.pid
    finally:
        devices.close()
    assert not _alive(pid)
    assert sim.process.exitcode == 0


def test_bad_arguments_are_the_simbench_message() -> None:
    with pytest.raises(ValueError, match="simulated bench: ValueError: SimBench: lever_arm_m"):
        SimBenchProcess(TRUTH, lever_arm_m=(0.0, float("nan"), 0.0))


OWNER = """
import sys, time
from drivers.sim.process import SimBenchProcess
sim = SimBenchProcess(None, speed=1.0, sample_rate_hz=50.0)
print(sim.pid, flush=True)
time.sleep(600)
"""


def test_the_simulator_ends_with_its_owner_killed() -> None:
    owner = subprocess.Popen([sys.executable, "-c", OWNER], cwd=REPO, stdout=subprocess.PIPE, text=True)
    try:
        assert owner.stdout is not None
        child = int(owner.stdout.readline())
        assert _alive(child)
        owner.send_signal(signal.SIGKILL)
        owner.wait(30)
        deadline = time.monotonic() + 60
        while _alive(child) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _alive(child), f"simulator {child} outlived its owner"
    finally:
        if owner.poll() is None:
            owner.kill()
