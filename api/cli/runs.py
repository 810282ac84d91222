"""``calbench runs [--json]``: list runs; runs whose process died show as ``interrupted``.

Before listing, live runs whose owner is gone are marked ``interrupted`` (same host: the
owner pid no longer exists; any host: no heartbeat for ``--stale-after-s``).

``--json`` prints a list of objects, newest first, with at least ``id``,
``unit_serial``, ``procedure`` and ``state`` (see ``db.models.RunState`` for the states).
"""

from __future__ import annotations

import argparse
import json
import socket
from typing import Any

from sqlalchemy.exc import OperationalError

from api.cli import BadInput, decimal_arg
from db.engine import describe_connection_error, make_session_factory
from db.migrate import open_database
from db.models import Run, RunState
from db.repo.recovery import DEFAULT_STALE_AFTER_S, mark_interrupted_runs
from db.repo.runs import list_runs


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print a JSON list instead of a table")
    parser.add_argument("--unit", metavar="SERIAL", help="only runs of this unit")
    parser.add_argument(
        "--state",
        action="append",
        choices=[s.value for s in RunState],
        help="only runs in this state (repeatable)",
    )
    parser.add_argument("--limit", type=int, default=None, help="at most this many runs (newest first)")
    parser.add_argument(
        "--database-url",
        default=None,
        help="database URL (default: CALBENCH_DATABASE_URL or the data directory)",
    )
    parser.add_argument(
        "--stale-after-s",
        type=decimal_arg,
        default=DEFAULT_STALE_AFTER_S,
        help="a live run without heartbeat for this long is interrupted (s)",
    )


def _iso(value: Any) -> str | None:
    return None if value is None else value.isoformat()


def run_as_dict(run: Run) -> dict[str, Any]:
    """The JSON object of one run (``run.unit`` and ``run.bench`` must be loaded)."""
    return {
        "id": run.id,
        "unit_serial": run.unit.serial,
        "procedure": run.procedure,
        "state": run.state.value,
        "outcome": run.outcome,
        "conformity_note": run.conformity_note or None,
        "progress": run.progress,
        "bench": run.bench.name if run.bench is not None else None,
        "created_at": _iso(run.created_at),
        "started_at": _iso(run.started_at),
        "finished_at": _iso(run.finished_at),
        "heartbeat_at": _iso(run.heartbeat_at),
        "last_complete_window": run.last_complete_window,
        "recording_path": run.recording_path,
        "owner": f"{run.owner_pid}@{run.owner_host}" if run.owner_pid is not None else None,
        "error": run.error,
    }


def _collect(args: argparse.Namespace) -> list[dict[str, Any]]:
    engine = open_database(args.database_url)
    try:
        factory = make_session_factory(engine)
        with factory.begin() as session:
            mark_interrupted_runs(session, socket.gethostname(), stale_after_s=args.stale_after_s)
        with factory() as session:
            states = [RunState(s) for s in args.state] if args.state else None
            runs = list_runs(session, unit_serial=args.unit, states=states, limit=args.limit)
            return [run_as_dict(r) for r in runs]
    finally:
        engine.dispose()


def run(args: argparse.Namespace) -> int:
    if args.limit is not None and args.limit < 1:
        raise BadInput(f"--limit must be >= 1, got {args.limit}")
    if not args.stale_after_s > 0:
        raise BadInput(f"--stale-after-s must be > 0, got {args.stale_after_s}")
    try:
        rows = _collect(args)
    except OperationalError as exc:
        raise BadInput(describe_connection_error(args.database_url, exc)) from exc
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    if not rows:
        print("no runs")
        return 0
    header = ("id", "unit", "procedure", "state", "outcome", "progress", "windows", "started")
    table = [header] + [
        (
            r["id"],
            r["unit_serial"],
            r["procedure"],
            r["state"],
            r["outcome"] or ("no conformity statement" if r["conformity_note"] else "-"),
            f"{100 * r['progress']:.0f}%",
            "-" if r["last_complete_window"] is None else str(r["last_complete_window"] + 1),
            (r["started_at"] or "-")[:19],
        )
        for r in rows
    ]
    widths = [max(len(str(row[i])) for row in table) for i in range(len(header))]
    for row in table:
        print("  ".join(str(v).ljust(w) for v, w in zip(row, widths, strict=True)).rstrip())
    return 0
