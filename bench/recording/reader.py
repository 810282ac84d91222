"""Read and validate a calbench-recording/1 (CSV samples + JSON sidecar).

The numeric columns are parsed by ``numpy.loadtxt`` in pieces of a megabyte into the
recording's preallocated arrays (about 1 s per million rows of seven columns; memory the result
plus one piece); only when that pass fails, or an optional column has empty fields, is the file walked
row by row to find and name the offending row. No row is
ever dropped: a row that cannot be used is an error.

Data rows are numbered from 1 (the first sample); CSV line numbers count the header as
line 1, so data row r is line r + 1.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from bench.inputs import (
    MAX_FIELD_CHARS,
    MAX_HEADER_CHARS,
    MAX_JSON_BYTES,
    InputError,
    check_text,
    loads_json,
    parse_decimal,
)
from bench.recording.errors import RecordingError
from bench.recording.model import FloatArray, Recording, Sidecar
from bench.recording.numeric_table import count_data_lines, load_columns
from bench.recording.sidecar import parse_sidecar

ACCEL_COLUMNS = ("ax", "ay", "az")
GYRO_COLUMNS = ("gx", "gy", "gz")
TEMP_COLUMN = "temp"
TIME_COLUMN = "t"
MAX_TABLE_ANGLE_DEG = 1e6
"""Largest encoder reading believed (deg, about 2800 turns): no table's encoder counts further, and
beyond it a double's resolution alone passes 1e-10°. Bench encoders wrap to ±180° or 0–360°."""
RATE_TOLERANCE = 0.2
"""``sample_rate_hz`` must agree with the median step of the time column within this fraction."""


def table_columns(n_axes: int) -> list[str]:
    """Names of the encoder columns for ``n_axes`` table axes: ``table_1`` … ``table_N``."""
    return [f"table_{i}" for i in range(1, n_axes + 1)]


def sidecar_path_for(csv_path: str | Path) -> Path:
    """The sidecar of a CSV: same stem, ``.json``."""
    return Path(csv_path).with_suffix(".json")


def read_sidecar(json_path: str | Path) -> Sidecar:
    """Read and validate a sidecar.

    :raises RecordingError: unreadable JSON, or a key that breaks the format.
    :raises FileNotFoundError: no such file.
    """
    p = Path(json_path)
    with p.open("rb") as f:
        raw = f.read(MAX_JSON_BYTES + 1)
    if len(raw) > MAX_JSON_BYTES:
        raise RecordingError(p, f"larger than {MAX_JSON_BYTES} bytes; a sidecar is a few kilobytes")
    try:
        obj = loads_json(raw.decode("utf-8"))
    except json.JSONDecodeError as exc:
        raise RecordingError(p, f"not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from exc
    except UnicodeDecodeError as exc:
        raise RecordingError(p, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from exc
    except InputError as exc:
        raise RecordingError(p, str(exc)) from exc
    return parse_sidecar(obj, p)


def read_header(csv_path: str | Path) -> list[str]:
    """Column names of a recording's CSV (line 1), validated: non-empty, no duplicates."""
    p = Path(csv_path)
    with p.open(encoding="utf-8-sig", newline="") as f:
        first = f.readline(MAX_HEADER_CHARS + 1)
    if len(first) > MAX_HEADER_CHARS:
        raise RecordingError(p, f"header line longer than {MAX_HEADER_CHARS} characters", line=1)
    if not first.strip():
        raise RecordingError(
            p, "empty file or empty header; expected a header row with t, ax, ay, az", line=1
        )
    try:
        names = [n.strip() for n in next(csv.reader([first]))]
    except csv.Error as exc:
        raise RecordingError(p, f"not CSV: {exc}", line=1) from None
    for i, n in enumerate(names):
        if not n:
            raise RecordingError(p, f"column {i + 1} has an empty name", line=1)
        try:
            check_text(n, max_chars=200)
        except InputError as exc:
            raise RecordingError(p, f"column {i + 1} name: {exc}", line=1) from None
        if names.index(n) != i:
            raise RecordingError(p, "duplicate column name", line=1, column=n)
    return names


def _expected_columns(names: list[str], sc: Sidecar, csv_p: Path, json_p: Path) -> None:
    """Check the header against the sidecar: required columns present, table columns match the axes."""
    for c in (TIME_COLUMN, *ACCEL_COLUMNS):
        if c not in names:
            raise RecordingError(csv_p, "missing required column", line=1, column=c)
    n_axes = len(sc.table.axes) if sc.table is not None else 0
    for c in table_columns(n_axes):
        if c not in names:
            raise RecordingError(
                csv_p,
                f"missing required column: the sidecar {json_p.name} lists {n_axes} "
                "table axes, so one encoder column per axis is required",
                line=1,
                column=c,
            )
    for c in names:
        if c.startswith("table_") and c not in table_columns(n_axes):
            raise RecordingError(
                csv_p,
                f"encoder column without a table axis: the sidecar {json_p.name} lists "
                f"{n_axes} table axes (table_1 … table_{n_axes})"
                if n_axes
                else f"encoder column, but the sidecar {json_p.name} has no 'table'",
                line=1,
                column=c,
            )
    gyro = [c for c in GYRO_COLUMNS if c in names]
    if gyro and len(gyro) != 3:
        missing = next(c for c in GYRO_COLUMNS if c not in names)
        raise RecordingError(csv_p, "gyro columns come as gx, gy, gz together", line=1, column=missing)
    if gyro and sc.gyro_unit is None:
        raise RecordingError(
            json_p,
            f"missing key: {csv_p.name} has gyro columns, so gyro_unit ('rad/s' or 'deg/s') is required",
            key="gyro_unit",
        )


def _rows(p: Path) -> Iterator[tuple[int, list[str]]]:
    """(line number, fields) of every line after the header, blank lines included as []."""
    with p.open(encoding="utf-8-sig", newline="") as f:
        reader = csv.reader(f)
        try:
            next(reader, None)
            for fields in reader:
                for x in fields:
                    if len(x) > MAX_FIELD_CHARS:
                        raise RecordingError(
                            p,
                            f"field of {len(x)} characters; expected at most {MAX_FIELD_CHARS}",
                            line=reader.line_num,
                        )
                yield reader.line_num, [x.strip(" \t") for x in fields]
        except csv.Error as exc:  # a field past the csv module's limit, a NUL, a stray quote
            problem = (
                f"field longer than {csv.field_size_limit()} characters; expected at most {MAX_FIELD_CHARS}"
                if "field limit" in str(exc)
                else f"not CSV: {exc}"
            )
            raise RecordingError(p, problem, line=reader.line_num) from None


def _parse_slow(
    p: Path, names: list[str], numeric: list[str], optional: set[str], extras: list[str]
) -> tuple[dict[str, FloatArray], dict[str, list[str]]]:
    """Row-by-row parse that names the first bad row; empty optional fields become NaN."""
    idx = [names.index(c) for c in numeric]
    values: list[list[float]] = [[] for _ in numeric]
    extra_idx = [names.index(c) for c in extras]
    extra_values: list[list[str]] = [[] for _ in extras]
    row = 0
    pending_blank: int | None = None
    for line, fields in _rows(p):
        if not fields or fields == [""]:
            pending_blank = pending_blank or line
            continue
        row += 1
        if pending_blank is not None:
            raise RecordingError(
                p, "blank line inside the data; expected one row per sample", line=pending_blank
            )
        if len(fields) != len(names):
            raise RecordingError(
                p, f"{len(fields)} fields, expected {len(names)} (one per header column)", row=row, line=line
            )
        for k, (c, j) in enumerate(zip(numeric, idx, strict=True)):
            s = fields[j]
            if s == "":
                if c in optional:
                    values[k].append(np.nan)
                    continue
                raise RecordingError(
                    p,
                    "missing value (empty field) in a required column; expected a number",
                    row=row,
                    line=line,
                    column=c,
                )
            try:
                x = parse_decimal(s)
            except InputError as exc:
                raise RecordingError(p, str(exc), row=row, line=line, column=c) from None
            values[k].append(x)
        for k, j in enumerate(extra_idx):
            extra_values[k].append(fields[j])
    cols = {c: np.asarray(v, dtype=float) for c, v in zip(numeric, values, strict=True)}
    return cols, dict(zip(extras, extra_values, strict=True))


def _parse_columns(
    p: Path, names: list[str], groups: dict[str, list[str]], optional: set[str]
) -> tuple[dict[str, FloatArray], dict[str, list[str]]]:
    """The numeric columns, by group, as (n, len(group)) float arrays, and the other columns as strings.

    :param groups: key -> column names (e.g. ``"accel"`` -> ax, ay, az); every numeric column in one group.

    Fast path (no unknown columns): ``loadtxt`` over all columns, chunk by chunk into the
    preallocated group arrays (``numeric_table.load_columns``), which also checks that every row
    has as many fields as the header. Otherwise, or when the fast path fails or sees non-finite values
    or skipped blank lines, the row-by-row parse runs and names the offending row.
    """
    numeric = [c for cols in groups.values() for c in cols]
    extras = [c for c in names if c not in numeric]
    n_lines = count_data_lines(p)
    if n_lines == 0:
        return {k: np.zeros((0, len(cols))) for k, cols in groups.items()}, {c: [] for c in extras}
    if not extras:
        idx = [[names.index(c) for c in cols] for cols in groups.values()]
        data = load_columns(p, n_lines, len(names), idx)
        if data is not None:
            return dict(zip(groups, data, strict=True)), {}
    cols, extra_cols = _parse_slow(p, names, numeric, optional, extras)
    n = cols[numeric[0]].shape[0]
    stacked = {k: np.column_stack([cols[c] for c in g]) if g else np.zeros((n, 0)) for k, g in groups.items()}
    return stacked, extra_cols


def _check_sample_rate(t: FloatArray, rate_hz: float, csv_p: Path, json_p: Path) -> None:
    """The sidecar's rate against the time column: the median step must be 1/rate within
    :data:`RATE_TOLERANCE` (the median ignores gaps and jitter; a rate off by a unit or a typo
    does not pass)."""
    if t.size < 2:
        return
    dt = float(np.median(np.diff(t)))
    ratio = dt * rate_hz
    if not (1.0 - RATE_TOLERANCE <= ratio <= 1.0 + RATE_TOLERANCE):
        raise RecordingError(
            json_p,
            f"sample_rate_hz = {rate_hz:g} Hz disagrees with the time column of {csv_p.name} "
            f"(median step {dt:.6g} s, i.e. {1.0 / dt:.6g} Hz); expected agreement within "
            f"{RATE_TOLERANCE:.0%}",
            key="sample_rate_hz",
        )


def _check_table_angles(table_deg: FloatArray, csv_p: Path) -> None:
    """Encoder readings beyond ±:data:`MAX_TABLE_ANGLE_DEG` are no table's: refuse the first one.

    Two comparisons, not ``abs``: boolean temporaries of n × axes bytes, not a float copy."""
    bad = np.argwhere((table_deg > MAX_TABLE_ANGLE_DEG) | (table_deg < -MAX_TABLE_ANGLE_DEG))
    if bad.size:
        r, k = (int(v) for v in bad[0])
        raise RecordingError(
            csv_p,
            f"encoder angle {float(table_deg[r, k])!r} deg is beyond ±{MAX_TABLE_ANGLE_DEG:g} deg; "
            "expected the table's reading (wrapped to ±180° or 0–360°, or a few turns)",
            row=r + 1,
            line=r + 2,
            column=f"table_{k + 1}",
        )


def read_recording(csv_path: str | Path) -> Recording:
    """Read a recording: ``run.csv`` and its sidecar ``run.json``.

    :returns: a :class:`Recording` with every row of the CSV.
    :raises RecordingError: any rule of ``docs/recording-format.md`` broken; the message names
        the file, the row/line or key, and what was expected.
    :raises FileNotFoundError: the CSV or its sidecar does not exist.
    """
    csv_p = Path(csv_path)
    json_p = sidecar_path_for(csv_p)
    if not csv_p.is_file():
        raise FileNotFoundError(f"{csv_p}: no such recording file")
    if not json_p.is_file():
        raise FileNotFoundError(f"{json_p}: sidecar of {csv_p.name} not found (same stem, .json)")
    sc = read_sidecar(json_p)
    try:
        names = read_header(csv_p)
    except UnicodeDecodeError as exc:
        raise RecordingError(csv_p, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from exc
    _expected_columns(names, sc, csv_p, json_p)
    n_axes = len(sc.table.axes) if sc.table is not None else 0
    has_gyro = "gx" in names
    groups = {"t": [TIME_COLUMN], "accel": list(ACCEL_COLUMNS), "table": table_columns(n_axes)}
    optional: set[str] = set()
    if TEMP_COLUMN in names:
        groups["temp"] = [TEMP_COLUMN]
        optional.add(TEMP_COLUMN)
    if has_gyro:
        groups["gyro"] = list(GYRO_COLUMNS)
        optional.update(GYRO_COLUMNS)
    try:
        cols, extra_cols = _parse_columns(csv_p, names, groups, optional)
    except UnicodeDecodeError as exc:
        raise RecordingError(csv_p, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from exc
    t = cols["t"].reshape(-1)
    if t.size == 0:
        raise RecordingError(csv_p, "no data rows; expected at least one sample after the header", line=2)
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        r = int(bad[0]) + 2
        raise RecordingError(
            csv_p,
            f"time stamp {float(t[r - 1])!r} s does not increase (previous row: {float(t[r - 2])!r} s); "
            "expected strictly increasing t",
            row=r,
            line=r + 1,
            column=TIME_COLUMN,
        )
    _check_sample_rate(t, sc.sample_rate_hz, csv_p, json_p)
    if n_axes:
        _check_table_angles(cols["table"], csv_p)
    if sc.segments:
        for i, s in enumerate(sc.segments):
            if s.start_s < t[0] or s.end_s > t[-1]:
                raise RecordingError(
                    json_p,
                    f"segment {s.label!r} [{s.start_s}, {s.end_s}] s lies outside the "
                    f"recording {csv_p.name} (t = {float(t[0])!r} … {float(t[-1])!r} s)",
                    key=f"segments[{i}]",
                )
    return Recording(
        sidecar=sc,
        t_s=t,
        accel_raw=cols["accel"],
        table_deg=cols["table"] if n_axes else None,
        temp_c=cols["temp"].reshape(-1) if "temp" in cols else None,
        gyro_raw=cols.get("gyro"),
        extra_columns=extra_cols,
        source=str(csv_p),
    )
