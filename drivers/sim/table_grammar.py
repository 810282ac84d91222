"""Controller side of the table protocol: command-line grammar and reply formatting.

The host never parses commands, so this lives with the simulated controller. Keywords
have a long form and the SCPI short form (the first four letters, or three when the
fourth is a vowel: ``DEMAND`` -> ``DEM``, ``POSITION`` -> ``POS``, ``STATUS`` -> ``STAT``).
A chained part without a leading ``:`` keeps the previous part's path:
``:READ:POSITION? 1;RATE? 1`` is ``:READ:POSITION? 1`` and ``:READ:RATE? 1``.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

from drivers.table_protocol import MAX_LINE_CHARS, ScpiError

_PRINTABLE = re.compile(r"^[\x20-\x7e]*$")

KEYWORDS = (
    "INTERLOCK",
    "CLOSE",
    "OPEN",
    "RESET",
    "MODE",
    "OFF",
    "POSITION",
    "RATE",
    "SYNTHESIS",
    "DEMAND",
    "DELTA",
    "OSCILLATION",
    "READ",
    "ACCELERATION",
    "STATUS",
    "LIMIT",
    "ABSOLUTE",
    "STOP",
    "ESTOP",
    "SYSTEM",
    "ERROR",
)


def short_form(keyword: str) -> str:
    """SCPI short form: the first four letters, or three when the fourth is a vowel."""
    if len(keyword) <= 4:
        return keyword
    return keyword[:3] if keyword[3] in "AEIOU" else keyword[:4]


_CANONICAL = {**{k: k for k in KEYWORDS}, **{short_form(k): k for k in KEYWORDS}}


class CommandSyntaxError(Exception):
    """A command line the controller cannot parse (an SCPI code and its text)."""

    def __init__(self, code: int, text: str) -> None:
        self.code = code
        self.text = text
        super().__init__(f"{code},{text}")


@dataclass(frozen=True)
class Command:
    """One parsed command: canonical long keywords, query flag, raw argument strings."""

    header: tuple[str, ...]
    query: bool
    args: tuple[str, ...]


def parse_command_line(line: str) -> list[Command]:
    """Split a command line into commands, expanding short forms and relative chain parts."""
    if len(line) > MAX_LINE_CHARS or not _PRINTABLE.match(line):
        raise CommandSyntaxError(ScpiError.SYNTAX, "Syntax error")
    commands: list[Command] = []
    path: tuple[str, ...] = ()
    for part in line.split(";"):
        part = part.strip()
        if not part:
            raise CommandSyntaxError(ScpiError.SYNTAX, "Syntax error")
        head, _, rest = part.partition(" ")
        query = head.endswith("?")
        head = head.removesuffix("?").upper()
        if head.startswith("*"):
            header: tuple[str, ...] = (head,)
        else:
            relative = not head.startswith(":")
            words = head.lstrip(":").split(":")
            try:
                canon = tuple(_CANONICAL[w] for w in words)
            except KeyError:
                raise CommandSyntaxError(ScpiError.UNDEFINED_HEADER, "Undefined header") from None
            header = (path[:-1] + canon) if relative else canon
            path = header
        args = tuple(a.strip() for a in rest.split(",")) if rest.strip() else ()
        commands.append(Command(header, query, args))
    return commands


def format_error(code: int, text: str) -> str:
    """``ERR <code>,"<text>"`` (double quotes in ``text`` become single quotes)."""
    return f'ERR {int(code)},"{text.replace(chr(34), chr(39))}"'


def format_error_entry(code: int, text: str) -> str:
    return f'{int(code)},"{text.replace(chr(34), chr(39))}"'


def format_status(status: int) -> str:
    return f"{int(status) & 0xFFFF:04X}"


def join_replies(parts: Iterable[str]) -> str:
    return ";".join(parts)
