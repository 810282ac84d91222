"""Server-sent events read back from a stream's lines (``docs/service.md``, event streams)."""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from typing import Any


def sse_events(lines: Iterable[str]) -> Iterator[tuple[str, dict[str, Any]]]:
    """``(event name, data object)`` for each ``event:`` / ``data:`` pair of the lines, in order.

    A ``data:`` line without a preceding ``event:`` line is named ``""``.
    """
    event = ""
    for line in lines:
        if line.startswith("event: "):
            event = line[7:]
        elif line.startswith("data: "):
            yield event, json.loads(line[6:])
