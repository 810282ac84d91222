"""A process of this host named by its pid and start time: alive, dead, or its pid reused."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from db.process import process_alive, process_ended, process_start_ticks, same_process_alive

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")


def test_the_start_time_is_read_past_a_command_name_with_spaces_and_parentheses(tmp_path: Path) -> None:
    # proc(5): "pid (comm) state ppid pgrp session tty_nr tpgid flags minflt cminflt majflt cmajflt
    # utime stime cutime cstime priority nice num_threads itrealvalue starttime ..."
    fields = ["S", "1", "2", "3", "4", "5", "6", "7", "8", "9", "10", "11", "12", "13", "14", "15", "16"]
    fields += ["20", "0", "123456", "999"]  # num_threads, itrealvalue, starttime, vsize
    (tmp_path / "42").mkdir()
    (tmp_path / "42" / "stat").write_text("42 (a) b (c) " + " ".join(fields) + "\n")
    assert process_start_ticks(42, proc=tmp_path) == 123456
    assert process_start_ticks(43, proc=tmp_path) is None


def test_a_killed_process_and_a_reused_pid_are_not_the_recorded_one() -> None:
    me = process_start_ticks(os.getpid())
    assert me is not None and same_process_alive(os.getpid(), me)
    assert not same_process_alive(os.getpid(), me + 1)  # the pid now names a later process
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        start = process_start_ticks(child.pid)
        assert start is not None and start >= me and same_process_alive(child.pid, start)
    finally:
        child.kill()
        child.wait(timeout=10)
    assert not process_alive(child.pid) and not same_process_alive(child.pid, start)


def test_a_killed_child_not_yet_collected_is_not_alive() -> None:
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        start = process_start_ticks(child.pid)
        assert not process_ended(child.pid)
        child.kill()
        deadline = time.monotonic() + 10
        while not process_ended(child.pid):  # until the kernel has ended it
            assert time.monotonic() < deadline
            time.sleep(0.01)
        assert process_alive(child.pid)  # kill(pid, 0) still finds the zombie
        assert not same_process_alive(child.pid, start) and not same_process_alive(child.pid, None)
    finally:
        child.kill()
        child.wait(timeout=10)
