"""Processes of this host: whether the process a database row names (pid and start time) is
still the one that wrote it.

A pid alone is not an identity: once a process has died the kernel may give its pid to a new
one. The start time of a process (Linux: field 22 of ``/proc/<pid>/stat``, clock ticks since
boot, ``proc(5)``) does not change while it lives and differs for a later process with the
same pid, so ``(pid, start)`` names one process for the life of the machine.
"""

from __future__ import annotations

import os
from pathlib import Path

PROC = Path("/proc")


def _stat_fields(pid: int, proc: Path) -> list[str] | None:
    """The fields of ``/proc/<pid>/stat`` from field 3 (state) on; ``None`` when unreadable."""
    try:
        stat = (proc / str(pid) / "stat").read_text()
    except OSError:
        return None
    # "pid (comm) state ppid ...": comm may hold spaces and parentheses
    return stat[stat.rfind(")") + 1 :].split()


def process_start_ticks(pid: int, proc: Path = PROC) -> int | None:
    """The start time of process ``pid`` (clock ticks since boot); ``None`` when it does not
    exist or the system does not tell (no ``/proc``)."""
    fields = _stat_fields(pid, proc)
    try:
        return int(fields[19]) if fields is not None else None  # field 22: the 20th from state
    except (IndexError, ValueError):
        return None


def process_ended(pid: int, proc: Path = PROC) -> bool:
    """Whether process ``pid`` has ended but its parent has not yet collected it (a zombie,
    state ``Z`` or ``X``: ``kill(pid, 0)`` still succeeds)."""
    fields = _stat_fields(pid, proc)
    if not fields:
        return False
    return fields[0] in ("Z", "X")


def process_alive(pid: int) -> bool:
    """Whether a process with ``pid`` exists on this host (``kill(pid, 0)``)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # exists, owned by another user
    return True


def same_process_alive(pid: int, start_ticks: int | None) -> bool:
    """Whether process ``pid`` of this host is alive and is the one that started at
    ``start_ticks`` (``None``: not recorded, the pid alone decides). A process that has ended
    and waits to be collected by its parent is not alive. When the start time of the live
    process cannot be read it is taken as the same one."""
    if not process_alive(pid) or process_ended(pid):
        return False
    if start_ticks is None:
        return True
    now = process_start_ticks(pid)
    return now is None or now == start_ticks
