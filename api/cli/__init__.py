"""The ``calbench`` command.

Each subcommand lives in its own module under ``api/cli/`` and exposes
``add_arguments(parser)`` and ``run(args) -> int``. Bad input ends with exit code 2 and
one line on stderr (see ``shared/cli-contract.md``).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "calibrate": ("api.cli.calibrate", "fit bias and scale/misalignment to a recording"),
    "diagnose": ("api.cli.diagnose", "find the physics the model left out, add it, refit"),
    "allan": ("api.cli.allan", "Allan deviation, noise terms and the dwell rule"),
    "convert": ("api.cli.convert", "convert another tool's data set into calbench-recording/1"),
    "simulate": ("api.cli.simulate", "write a simulated recording with chosen effects"),
    "run": ("api.cli.run", "run a calibration procedure on the bench"),
    "runs": ("api.cli.runs", "list runs"),
    "resume": ("api.cli.resume", "resume an interrupted run"),
    "serve": ("api.cli.serve", "start the REST service and dashboard"),
    "agent": ("api.cli.agent", "run the bench agent: the process that owns the table and DAQ"),
    "db": ("api.cli.db", "database maintenance (upgrade)"),
}


class BadInput(Exception):
    """Input the command cannot use; the message is printed as one line, exit code 2."""


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every subcommand whose module is installed."""
    parser = argparse.ArgumentParser(prog="calbench", description="accelerometer calibration bench")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                continue
            raise
        p = sub.add_parser(name, help=help_text, description=help_text)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``calbench`` script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._run(args))
    except BadInput as exc:
        print(f"calbench {args.command}: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        # Validation errors from bench/ are ValueErrors whose message names file, key and expectation.
        print(f"calbench {args.command}: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
