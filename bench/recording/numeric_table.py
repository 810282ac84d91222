"""The fast path of the recording reader: a CSV's numeric rows parsed in pieces into preallocated arrays.

Used by :mod:`bench.recording.reader`, which validates the header first and, whenever
:func:`load_columns` answers None, walks the file row by row to name the offending row.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from bench.recording.model import FloatArray


def count_data_lines(p: Path) -> int:
    """Lines after the header, not counting trailing blank lines (fast, in binary chunks)."""
    newlines = 0
    with p.open("rb") as f:
        while chunk := f.read(1 << 22):
            newlines += chunk.count(b"\n")
        size = f.tell()
        f.seek(max(0, size - (1 << 16)))
        tail = f.read()
    trailing = tail[len(tail.rstrip(b"\r\n \t")) :].count(b"\n")
    return newlines - trailing


CHUNK_BYTES = 1 << 20
"""Bytes of CSV text parsed per ``loadtxt`` call by the fast path (whole lines, about 10 000 rows)."""


def load_columns(p: Path, n_rows: int, n_fields: int, groups: list[list[int]]) -> list[FloatArray] | None:
    """The data rows' columns ``groups`` (field indices) as (n_rows, len(group)) arrays, or None.

    The text after the header is cut into pieces of about :data:`CHUNK_BYTES` at line ends; each
    piece is parsed by ``numpy.loadtxt`` and its columns copied into their rows of the
    preallocated group arrays, so the memory held is the result plus one piece (not
    ``loadtxt``'s growing buffer and copies of the whole table). None when a piece does not
    parse, a row has another field count than ``n_fields``, the rows do not number ``n_rows``
    (blank lines, which ``loadtxt`` skips) or a value is not finite: the row-by-row parse then
    names the offending row.
    """
    outs = [np.empty((n_rows, len(g))) for g in groups]
    row = 0
    with p.open("rb") as f:
        f.readline()  # the header (read_header validated it)
        tail = b""
        while True:
            block = f.read(CHUNK_BYTES)
            text = tail + block
            if block:
                cut = text.rfind(b"\n") + 1
                text, tail = text[:cut], text[cut:]
            if text.strip():
                try:
                    part = np.loadtxt(
                        io.StringIO(text.decode("utf-8")),
                        delimiter=",",
                        comments=None,
                        ndmin=2,
                        quotechar='"',
                        dtype=float,
                    )
                except ValueError:  # a bad number, a field count, bad UTF-8
                    return None
                k = part.shape[0]
                if part.shape[1] != n_fields or row + k > n_rows or not np.all(np.isfinite(part)):
                    return None
                for out, g in zip(outs, groups, strict=True):
                    out[row : row + k] = part[:, g]
                row += k
            if not block:
                break
    return outs if row == n_rows else None
