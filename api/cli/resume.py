"""``calbench resume RUN_ID [--sim] [--sim-speed N]``: finish an interrupted run.

The recording is cut back to the last durable chunk that holds the last complete window,
and the procedure continues with the next window; the end is as ``calbench run`` (a device
fault is resumed automatically as there, :mod:`station.execution.fault_retry`; exit code 4 and
the command that continues it for a run still interrupted after the last try).
"""

from __future__ import annotations

import argparse
import sys

from api.cli.run import (
    ProgressBar,
    add_device_arguments,
    holding_bench,
    install_abort_handler,
    report,
    resume_command,
    settings_for,
)
from bench.records import RunRecord
from bench.sequencer.control import RunControl
from station.execution.bench_lock import HELD_EXIT
from station.execution.continuation import resume_run
from station.execution.fault_retry import run_resuming


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench resume``."""
    parser.add_argument("run_id", metavar="RUN_ID", help="id of the run (see calbench runs)")
    add_device_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Execute ``calbench resume`` (exit code 3, one line, when another process drives the bench)."""
    settings = settings_for(args)
    lock = holding_bench(settings, "calbench resume", sim=args.sim)
    if lock is None:
        return HELD_EXIT
    try:
        control = RunControl()
        install_abort_handler(control)
        observers = [] if args.json else [ProgressBar()]

        def resume(run_id: str) -> RunRecord:
            return resume_run(
                settings, run_id, sim=args.sim, sim_speed=args.sim_speed, observers=observers, control=control
            )

        record = run_resuming(
            lambda: resume(args.run_id),
            resume,
            control,
            say=lambda msg: print(f"calbench resume: {msg}", file=sys.stderr),
        )
        return report(record, args.json, resume_command(args, record.run_id))
    finally:
        lock.release()
