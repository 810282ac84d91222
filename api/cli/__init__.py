"""The ``calbench`` command.

Each subcommand lives in its own module under ``api/cli/`` and exposes
``add_arguments(parser)`` and ``run(args) -> int``. Bad input ends with exit code 2 and
one line on stderr (see ``docs/cli-contract.md``).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings
from collections.abc import Sequence

from bench.inputs import InputError, parse_decimal

SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "calibrate": ("api.cli.calibrate", "fit bias and scale/misalignment to a recording"),
    "diagnose": ("api.cli.diagnose", "find the physics the model left out, add it, refit"),
    "allan": ("api.cli.allan", "Allan deviation, noise terms and the dwell rule"),
    "export": ("api.cli.export", "write the fitted correction for imucal, Kalibr, C firmware or JSON"),
    "convert": ("api.cli.convert", "convert another tool's data set into calbench-recording/1"),
    "simulate": ("api.cli.simulate", "write a simulated recording with chosen effects"),
    "plan": (
        "api.cli.plan",
        "design the procedure that reaches target uncertainties in the least table time",
    ),
    "run": ("api.cli.run", "run a calibration procedure on the bench"),
    "runs": ("api.cli.runs", "list runs"),
    "resume": ("api.cli.resume", "resume an interrupted run"),
    "serve": ("api.cli.serve", "start the REST service and dashboard"),
    "agent": ("api.cli.agent", "run the bench agent: the process that owns the table and DAQ"),
    "db": ("api.cli.db", "database maintenance (upgrade)"),
}

HOLD_WARNINGS = frozenset({"calibrate", "diagnose", "allan", "convert", "simulate"})
"""Commands that compute one answer: their warnings are held and printed after it, one line each."""


class BadInput(Exception):
    """Input the command cannot use; the message is printed as one line, exit code 2."""


def decimal_arg(text: str) -> float:
    """argparse ``type`` for a number: ASCII decimal and finite (see :mod:`bench.inputs`)."""
    try:
        return parse_decimal(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _command_in(argv: Sequence[str]) -> str | None:
    """The subcommand named in ``argv`` (its first word that is not an option), if any."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in SUBCOMMANDS else None
    return None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The top-level parser; only ``command``'s module is imported (its arguments added).

    Every subcommand is listed with its help line; importing a subcommand's module (numpy,
    scipy, the service) is paid only by the command that runs, so ``calbench --help`` and
    each command start without the others' imports. ``command=None`` imports none.
    """
    parser = argparse.ArgumentParser(prog="calbench", description="accelerometer calibration bench")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if name != command:
            continue
        module = importlib.import_module(module_name)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


PRIVATE_FILES = frozenset({"serve", "agent", "run", "resume", "db"})
"""Commands that create the database, recordings and certificates: their files are created
readable by their owner only (umask 077: files 0600, directories 0700)."""


def _one_line(text: str) -> str:
    """A message as one line: line breaks become ' / '."""
    return " / ".join(part.strip() for part in str(text).splitlines() if part.strip())


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``calbench`` script.

    Bad input (``BadInput``, a ``ValueError`` from bench/, a file that cannot be read) ends
    with exit code 2 and exactly one line on stderr. Numerical warnings raised on the way
    (numpy's ``RuntimeWarning``...) are held back: with bad input they are dropped (the one
    line says what is wrong); after a result they follow it on stderr, one line each, so an
    answer computed with a warning never goes out without it.
    """
    words = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(_command_in(words))
    args = parser.parse_args(words)
    hold = args.command in HOLD_WARNINGS
    if args.command in PRIVATE_FILES:
        os.umask(0o077)
    with warnings.catch_warnings(record=hold) as caught:
        if hold:
            warnings.simplefilter("always")
        try:
            code = int(args._run(args))
        except BadInput as exc:
            print(f"calbench {args.command}: {_one_line(str(exc))}", file=sys.stderr)
            return 2
        except BrokenPipeError:  # the reader went away (``| head``): not bad input
            raise
        except (ValueError, OSError) as exc:
            # Validation errors from bench/ are ValueErrors whose message names file, key and
            # expectation; an OSError names the file that could not be read or written.
            print(f"calbench {args.command}: {_one_line(str(exc))}", file=sys.stderr)
            return 2
    seen: set[str] = set()
    for w in caught or ():
        text = f"{w.category.__name__}: {_one_line(str(w.message))}"
        if text not in seen:
            seen.add(text)
            print(f"calbench {args.command}: warning: {text}", file=sys.stderr)
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
