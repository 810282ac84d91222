"""``make bench`` writes what it measured into docs/benchmarks.md: each benchmark's block of
output replaced by the new one, so the figures there are the last run's.

A block is the benchmark's output as ``python -m benchmarks`` prints it: the title line
``=== bench_x ===``, its lines, and the closing ``(N s)`` line, to which the recording adds the
date and the load average (``(0.6 s; recorded 2026-11-27, load average 3.1)``). The first block
of that title in the file is replaced; a benchmark without one is added at the end of the
file's first code block. The text around the blocks (what the numbers mean, studies) is not
touched: where a run changes what it says, the text needs a new reading.
"""

from __future__ import annotations

import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "benchmarks.md"
_END = re.compile(r"^\([0-9.]+ s[;)].*$", re.MULTILINE)


def replace_block(doc: str, name: str, block: str) -> str:
    """``doc`` with the block of benchmark ``name`` replaced by ``block`` (which starts with its
    title line and ends with its ``(N s…)`` line), or added at the end of the first code block.

    :raises ValueError: ``block`` is not one benchmark's block, or the document has a title
        without its closing line, or no code block to add a new one to.
    """
    title = f"=== {name} ==="
    block = block.strip("\n")
    if not block.startswith(title) or not _END.search(block.splitlines()[-1]):
        raise ValueError(f"{name}: expected a block from {title!r} to its '(N s)' line")
    start = doc.find(title + "\n")
    if start >= 0:
        end = _END.search(doc, start)
        if end is None:
            raise ValueError(f"docs/benchmarks.md: {title} has no closing '(N s)' line")
        return doc[:start] + block + doc[end.end() :]
    fence = doc.find("```\n")
    close = doc.find("\n```", fence + 4) if fence >= 0 else -1
    if close < 0:
        raise ValueError("docs/benchmarks.md: no code block to add a benchmark's output to")
    return doc[:close] + "\n\n" + block + doc[close:]


def record(name: str, output: str, elapsed_s: float, date: str, load: float, doc_path: Path = DOC) -> None:
    """Write one benchmark's output into ``doc_path`` (module docstring)."""
    block = (
        f"=== {name} ===\n{output.rstrip()}\n({elapsed_s:.1f} s; recorded {date}, load average {load:.1f})"
    )
    doc_path.write_text(replace_block(doc_path.read_text(encoding="utf-8"), name, block), encoding="utf-8")
