"""The one error of the recording package: input that is not a valid calbench-recording/1.

A :class:`RecordingError` is a :class:`ValueError` whose message names the file, the
place in it (data row and CSV line number, column, or sidecar key) and what was
expected, so one line on stderr tells an operator what to fix.
"""

from __future__ import annotations

from pathlib import Path


class RecordingError(ValueError):
    """A recording (CSV or sidecar) that breaks a rule of ``docs/recording-format.md``.

    :param path: the offending file.
    :param problem: what is wrong and what was expected.
    :param row: 1-based data row (the first sample is row 1), if the problem is in a row.
    :param line: 1-based line number in the CSV file (the header is line 1).
    :param column: CSV column name, if known.
    :param key: sidecar key as a dotted path (``table.axes[1].axis``), if the problem is a key.
    """

    def __init__(
        self,
        path: str | Path,
        problem: str,
        *,
        row: int | None = None,
        line: int | None = None,
        column: str | None = None,
        key: str | None = None,
    ) -> None:
        self.path = str(path)
        self.problem = problem
        self.row = row
        self.line = line
        self.column = column
        self.key = key
        where: list[str] = []
        if row is not None:
            where.append(f"data row {row}")
        if line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column '{column}'")
        if key is not None:
            where.append(f"key '{key}'")
        place = f" ({', '.join(where)})" if where else ""
        super().__init__(f"{self.path}{place}: {problem}")
