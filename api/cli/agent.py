"""``calbench agent [--sim] [--sim-speed N]``: the process that owns one bench (table, DAQ,
sequencer, recording) and executes the runs queued for it in the database.

Settings come from ``CALBENCH_*`` like the service's (``CALBENCH_BENCH_NAME`` names the
bench, ``CALBENCH_DATABASE_URL`` the shared database, ``CALBENCH_TABLE_URL`` /
``CALBENCH_DAQ_URL`` the devices). One agent per bench: a second one on the same host and
data directory, or sharing its database from another host, exits with code 3 and one line
naming the process that drives the bench — an agent, or ``calbench run`` — (the OS lock
``<data_dir>/bench-<bench>.lock`` and the database lease, :mod:`station.execution.bench_lock`). If
the lease is taken from it (it stalled past the lease), it stops, leaving its run
``interrupted``. SIGTERM or SIGINT stop it with the run it holds
``interrupted`` (table safe, recording closed, resumable).
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading

from api.cli import BadInput
from station.execution.bench_lock import HELD_EXIT, BenchHeld, BenchLock
from station.settings import Settings

ALREADY_RUNNING = HELD_EXIT
"""Exit code when another process (an agent, ``calbench run``) holds the bench."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench agent``."""
    parser.add_argument("--sim", action="store_true", help="drive a simulated bench (its own process)")
    parser.add_argument(
        "--sim-speed", type=float, default=None, metavar="N", help="simulated seconds per wall second"
    )
    parser.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])


def agent_settings(args: argparse.Namespace) -> Settings:
    """Settings from the environment and the flags.

    :raises BadInput: a bad speed or environment value, or a simulation the DAQ link cannot carry.
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
    final = settings.model_copy(update=update)
    if final.sim:
        from station.execution.devices import check_sim_link

        try:
            check_sim_link(final.sim_speed, final.sim_sample_rate_hz)
        except ValueError as exc:
            raise BadInput(str(exc)) from None
    return final


def run(args: argparse.Namespace) -> int:
    """Execute ``calbench agent``."""
    from station.agent.bench_agent import BenchAgent

    settings = agent_settings(args)
    stop = threading.Event()
    lock = BenchLock(settings, "calbench agent", on_lost=lambda why: stop.set())
    try:
        lock.acquire()
    except BenchHeld as exc:
        print(f"calbench agent: {exc}", file=sys.stderr)
        return ALREADY_RUNNING
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(levelname)s %(message)s")

    def handler(signum: int, frame: object) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        agent = BenchAgent(settings, lease_token=lock.token)
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
        lock.release()
    return 0
