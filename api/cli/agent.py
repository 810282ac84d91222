"""``calbench agent [--sim] [--sim-speed N]``: the process that owns one bench (table, DAQ,
sequencer, recording) and executes the runs queued for it in the database.

Settings come from ``CALBENCH_*`` like the service's (``CALBENCH_BENCH_NAME`` names the
bench, ``CALBENCH_DATABASE_URL`` the shared database, ``CALBENCH_TABLE_URL`` /
``CALBENCH_DAQ_URL`` the devices). One agent per bench: a second one on the same host and
data directory exits with code 3 and names the first one's pid (the lock file
``<data_dir>/agent-<bench>.lock``). SIGTERM or SIGINT stop it with the run it holds
``interrupted`` (table safe, recording closed, resumable).
"""

from __future__ import annotations

import argparse
import fcntl
import logging
import os
import re
import signal
import sys
import threading
from pathlib import Path
from typing import IO

from api.cli import BadInput
from api.settings import Settings

ALREADY_RUNNING = 3
"""Exit code when another agent holds the bench."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench agent``."""
    parser.add_argument("--sim", action="store_true", help="drive a simulated bench (its own process)")
    parser.add_argument(
        "--sim-speed", type=float, default=None, metavar="N", help="simulated seconds per wall second"
    )
    parser.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])


def agent_settings(args: argparse.Namespace) -> Settings:
    """Settings from the environment and the flags.

    :raises BadInput: a bad speed or environment value.
    """
    try:
        settings = Settings()
    except ValueError as exc:
        raise BadInput(str(exc).splitlines()[0]) from None
    update: dict[str, object] = {"agent": "embedded"}
    if args.sim:
        update["sim"] = True
    if args.sim_speed is not None:
        if not args.sim_speed > 0:
            raise BadInput(f"--sim-speed {args.sim_speed}: expected a positive number")
        update["sim_speed"] = args.sim_speed
    return settings.model_copy(update=update)


def lock_path(settings: Settings) -> Path:
    """The bench's agent lock file: ``<data_dir>/agent-<bench>.lock`` (it holds the agent's pid)."""
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", settings.bench_name)[:100]
    return settings.data_dir / f"agent-{safe}.lock"


def take_lock(path: Path, *, write_pid: bool = True) -> IO[str] | None:
    """Hold the lock file (it stays held while the returned file is open) and write this
    process's pid into it; ``None`` when another process holds it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle = path.open("a+")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.close()
        return None
    if write_pid:
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()}\n")
        handle.flush()
    return handle


def lock_holder(path: Path) -> int | None:
    """The pid written in the lock file, if the lock is held; ``None`` when it is free (the
    check holds the lock for an instant: an agent starting just then exits with
    :data:`ALREADY_RUNNING`, and its supervisor starts it again)."""
    handle = take_lock(path, write_pid=False)
    if handle is not None:
        handle.close()
        return None
    try:
        return int(path.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return -1


def run(args: argparse.Namespace) -> int:
    """Execute ``calbench agent``."""
    from api.agent.bench_agent import BenchAgent

    settings = agent_settings(args)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(levelname)s %(message)s")
    lock = take_lock(lock_path(settings))
    if lock is None:
        print(
            f"calbench agent: bench {settings.bench_name!r} already has an agent "
            f"(pid {lock_holder(lock_path(settings))}, lock {lock_path(settings)})",
            file=sys.stderr,
        )
        return ALREADY_RUNNING
    stop = threading.Event()

    def handler(signum: int, frame: object) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        agent = BenchAgent(settings)
        print(
            f"calbench agent: bench {settings.bench_name!r}, pid {os.getpid()}, database "
            f"{settings.effective_database_url}, {'simulated bench' if settings.sim else settings.table_url}",
            file=sys.stderr,
        )
        agent.start()
        while not stop.wait(1.0):
            pass
        agent.stop()
        agent.close()
    finally:
        for sig, prev in previous.items():
            signal.signal(sig, prev)
        lock.close()
    return 0
