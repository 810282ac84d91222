"""``calbench db upgrade|current``: database maintenance.

``upgrade`` brings the database (``--database-url``, else ``CALBENCH_DATABASE_URL``,
else SQLite in the data directory) to the newest schema; ``current`` prints its revision.
"""

from __future__ import annotations

import argparse

from sqlalchemy.engine import Engine
from sqlalchemy.exc import OperationalError

from api.cli import BadInput
from db.engine import describe_connection_error, make_engine
from db.migrate import current_revision, head_revision, upgrade


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "action", choices=["upgrade", "current"], help="upgrade to the newest schema, or show it"
    )
    parser.add_argument(
        "--database-url",
        default=None,
        help="database URL (default: CALBENCH_DATABASE_URL or the data directory)",
    )


def _act(engine: Engine, action: str) -> str:
    where = engine.url.render_as_string(hide_password=True)
    before = current_revision(engine)
    if action == "upgrade":
        upgrade(engine)
        return f"{where}: {before or 'empty'} -> {current_revision(engine)}"
    head = head_revision()
    status = "up to date" if before == head else f"behind (newest is {head})"
    return f"{where}: {before or 'empty'} ({status})"


def run(args: argparse.Namespace) -> int:
    engine = make_engine(args.database_url)
    try:
        print(_act(engine, args.action))
    except OperationalError as exc:
        raise BadInput(describe_connection_error(args.database_url, exc)) from exc
    finally:
        engine.dispose()
    return 0
