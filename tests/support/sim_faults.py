"""Faults a lab's bench shows, injected into a simulated bench running in its own process
(:class:`drivers.sim.process.SimBenchProcess`) from outside, as the real world would: the
process stalls (SIGSTOP for a while, then SIGCONT: a controller that hangs and comes back) or
dies (SIGKILL: a reset, every link dropped)."""

from __future__ import annotations

import contextlib
import os
import signal
import time
from pathlib import Path


def child_pids(pid: int) -> list[int]:
    """The direct children of process ``pid`` (Linux ``/proc``)."""
    out = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rfind(")") + 2 :].split()
        if len(fields) > 1 and int(fields[1]) == pid:
            out.append(int(entry.name))
    return out


def sim_pid(owner_pid: int) -> int | None:
    """The simulated bench process started by ``owner_pid`` (its ``calbench-sim`` child), if any."""
    for child in child_pids(owner_pid):
        try:
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
        except OSError:
            continue
        if b"multiprocessing" in cmdline and b"spawn" in cmdline:
            return child
    return None


def stall(pid: int, seconds: float) -> None:
    """Freeze process ``pid`` for ``seconds`` (SIGSTOP, then SIGCONT)."""
    os.kill(pid, signal.SIGSTOP)
    try:
        time.sleep(seconds)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGCONT)


def kill(pid: int) -> None:
    """End process ``pid`` at once (SIGKILL)."""
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)


def lose_line(pid: int) -> None:
    """Cut the table's connections of simulator process ``pid``, which runs on (SIGUSR1)."""
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGUSR1)
