"""``make bench --record``: a benchmark's block in docs/benchmarks.md is replaced, the rest kept."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks.record import DOC, record, replace_block

DOC_TEXT = """# Benchmark results

```
=== bench_a ===
a: 1.00
(0.5 s)

=== bench_b ===
b: 6.40x
two lines
(0.6 s; recorded 2026-11-22, load average 2.0)
```

## What bench_b means

It says 6.40x.
"""


def test_a_block_is_replaced_and_nothing_else_moves(tmp_path: Path) -> None:
    doc = tmp_path / "benchmarks.md"
    doc.write_text(DOC_TEXT)
    record("bench_b", "b: 21.30x\n", 0.7, "2026-11-27", 3.14, doc)
    text = doc.read_text()
    assert "=== bench_b ===\nb: 21.30x\n(0.7 s; recorded 2026-11-27, load average 3.1)\n```" in text
    assert "two lines" not in text and "b: 6.40x" not in text
    assert text.startswith(DOC_TEXT[: DOC_TEXT.index("=== bench_b")])  # bench_a and the head untouched
    assert text.endswith("## What bench_b means\n\nIt says 6.40x.\n")  # prose is not rewritten


def test_a_new_benchmark_goes_at_the_end_of_the_first_code_block() -> None:
    text = replace_block(DOC_TEXT, "bench_c", "=== bench_c ===\nc\n(1.0 s)")
    assert "(0.6 s; recorded 2026-11-22, load average 2.0)\n\n=== bench_c ===\nc\n(1.0 s)\n```" in text


def test_a_malformed_block_or_document_is_refused() -> None:
    with pytest.raises(ValueError, match="expected a block from '=== bench_a ==='"):
        replace_block(DOC_TEXT, "bench_a", "=== bench_a ===\nno end line")
    with pytest.raises(ValueError, match="has no closing"):
        replace_block("=== bench_a ===\nx\n", "bench_a", "=== bench_a ===\ny\n(1 s)")


def test_every_block_of_the_projects_document_has_its_closing_line() -> None:
    text = DOC.read_text()
    for line in text.splitlines():
        if line.startswith("=== bench_"):
            name = line.strip("= ")
            assert replace_block(text, name, f"=== {name} ===\nx\n(1.0 s)").count(f"=== {name} ===") >= 1
