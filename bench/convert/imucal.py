"""imucal's Ferraris example sessions -> calbench-recording/1.

Source (imucal, mad-lab-fau, MIT; docs/real-datasets.md):

* ``example_ferraris_session.csv`` — one continuous session, columns ``n_samples, gyr_x,
  gyr_y, gyr_z, acc_x, acc_y, acc_z`` in m/s² and °/s, with the authors' annotation
  ``example_ferraris_session_list.json``: ``{"x_p": {"start": i, "end": j}, …}``, sample
  indices, ``end`` exclusive (``iloc[start:end]``).
* ``annotated_session.csv`` — another session in raw counts, already cut into its nine
  parts and concatenated: columns ``part, samples, acc_x, acc_y, acc_z, gyr_x, gyr_y,
  gyr_z``; ``samples`` numbers the kept samples 0 … n−1 in time order (the file lists the
  parts alphabetically, so rows are put back in ``samples`` order). The time between parts
  was cut away, so time in the converted file runs on without those gaps.

Time is ``t = index / sample_rate_hz``; the rate is not in the files and must be given
(102.4 Hz and 204.8 Hz for the two sessions: the README's note on imucal issue #25).
The hand-held unit has no table. Each labelled part becomes a segment: ``x_p`` … ``z_a``
get ``nominal_up`` ``+x`` … ``-z`` (imucal: ``x_p`` = +x along gravity, reading +1 g,
which in the format's convention is +x pointing up), after checking that the data agree
(that axis carries most of the reading with that sign); ``x_rot`` … keep their label and no
``nominal_up``. Accelerometer units are stated as they are (``m/s2`` or ``count``); gyro
counts, which ``gyro_unit`` cannot express, go to extra columns ``gyr_x_counts`` ….
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bench.recording.model import Recording, Segment, Sidecar

G_LOCAL_M_S2 = 9.81
"""imucal's default expected gravity; the lab's local value is not published."""
SESSION_HEADER = ["n_samples", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z"]
ANNOTATED_HEADER = ["part", "samples", "acc_x", "acc_y", "acc_z", "gyr_x", "gyr_y", "gyr_z"]
UP_OF_PART = {"x_p": "+x", "x_a": "-x", "y_p": "+y", "y_a": "-y", "z_p": "+z", "z_a": "-z"}
_SOURCE = {
    "dataset": "imucal example data (mad-lab-fau/imucal, JOSS 2022), Ferraris 6-position + 3-rotation",
    "repository": "mad-lab-fau/imucal@8716e4c50bbb7044918b747f38b26cb0a6420910",
    "licence": "MIT",
    "protocol": "hand-held, no table: six still poses (x_p … z_a) and three 360° turns (x_rot … z_rot)",
    "g_local_note": "9.81 m/s² is imucal's default, not a measured local value",
}


def _header(path: Path) -> list[str]:
    with path.open(encoding="utf-8", newline="") as f:
        return [h.strip() for h in next(csv.reader(f), [])]


def _numeric(path: Path, usecols: Sequence[int]) -> np.ndarray:
    try:
        data = np.loadtxt(
            path, delimiter=",", skiprows=1, usecols=usecols, comments=None, ndmin=2, dtype=float
        )
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    finite = np.all(np.isfinite(data), axis=1)
    if not np.all(finite):
        raise ValueError(
            f"{path} (data row {int(np.argmin(finite)) + 1}): non-finite value; expected numbers"
        )
    return data


def _check_rate(sample_rate_hz: float) -> None:
    if not (np.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"sample_rate_hz must be a positive number, got {sample_rate_hz}")


def _segments(
    path: Path, parts: dict[str, tuple[int, int]], t: np.ndarray, acc: np.ndarray
) -> tuple[Segment, ...]:
    """Segments from (first, last) sample indices per part, nominal_up checked against the data."""
    segs = []
    for label, (first, last) in sorted(parts.items(), key=lambda kv: kv[1][0]):
        if not (0 <= first < last < t.shape[0]):
            raise ValueError(
                f"{path}: part {label!r} spans samples {first}…{last}, outside 0…{t.shape[0] - 1}"
            )
        up = UP_OF_PART.get(label)
        if up is not None:
            mean = acc[first : last + 1].mean(axis=0)
            axis = "xyz".index(up[1])
            sign = 1.0 if up[0] == "+" else -1.0
            if int(np.argmax(np.abs(mean))) != axis or sign * mean[axis] <= 0:
                raise ValueError(
                    f"{path}: part {label!r} should read gravity on {up} but its mean is {mean.tolist()}; "
                    "labels and data disagree"
                )
        segs.append(Segment(start_s=float(t[first]), end_s=float(t[last]), label=label, nominal_up=up))
    return tuple(segs)


def _count_text(values: np.ndarray) -> list[str]:
    if np.all(values == np.round(values)):
        return [str(v) for v in values.astype(np.int64).tolist()]
    return [repr(v) for v in values.tolist()]


def read_imucal_session(
    csv_path: str | Path, sections_path: str | Path, sample_rate_hz: float, g_local_m_s2: float = G_LOCAL_M_S2
) -> Recording:
    """Read ``example_ferraris_session.csv`` (m/s², °/s) with its section list.

    :param csv_path: the session CSV.
    :param sections_path: the JSON section list (``end`` exclusive).
    :param sample_rate_hz: the session's rate (102.4 Hz for the shipped example).
    :param g_local_m_s2: local gravity to record in the sidecar.
    :raises ValueError: wrong header, bad values, sample numbers not consecutive, bad sections.
    """
    p, sp = Path(csv_path), Path(sections_path)
    _check_rate(sample_rate_hz)
    if _header(p) != SESSION_HEADER:
        raise ValueError(f"{p} (line 1): header {_header(p)}, expected {', '.join(SESSION_HEADER)}")
    data = _numeric(p, range(7))
    n = data[:, 0]
    if not np.array_equal(n, np.arange(n.shape[0])):
        row = int(np.argmax(n != np.arange(n.shape[0]))) + 1
        raise ValueError(f"{p} (data row {row}): n_samples is not consecutive from 0")
    t = n / sample_rate_hz
    try:
        sections = json.loads(sp.read_text(encoding="utf-8"))
        parts = {k: (int(v["start"]), int(v["end"]) - 1) for k, v in sections.items()}
    except (json.JSONDecodeError, KeyError, TypeError, ValueError, AttributeError) as exc:
        raise ValueError(f"{sp}: expected {{part: {{start, end}}}} sample indices ({exc})") from None
    acc = data[:, 4:7]
    sidecar = Sidecar(
        unit_serial="unknown",
        unit_model="MaD-Lab FAU 6-DOF unit (not named in the source)",
        channel_unit="m/s2",
        gyro_unit="deg/s",
        sample_rate_hz=sample_rate_hz,
        g_local_m_s2=g_local_m_s2,
        procedure="ferraris-6+3",
        segments=_segments(sp, parts, t, acc),
        extra={"source": {**_SOURCE, "files": [p.name, sp.name]}},
    )
    return Recording(
        sidecar=sidecar,
        t_s=t,
        accel_raw=np.ascontiguousarray(acc),
        gyro_raw=np.ascontiguousarray(data[:, 1:4]),
        source=str(p),
    )


def read_imucal_annotated(
    csv_path: str | Path, sample_rate_hz: float, g_local_m_s2: float = G_LOCAL_M_S2
) -> Recording:
    """Read ``annotated_session.csv`` (raw counts, parts already cut).

    :param csv_path: the annotated CSV.
    :param sample_rate_hz: the session's rate (204.8 Hz for the shipped example).
    :param g_local_m_s2: local gravity to record in the sidecar.
    :raises ValueError: wrong header, bad values, ``samples`` not a permutation of 0…n−1,
        or a part whose samples are not contiguous.
    """
    p = Path(csv_path)
    _check_rate(sample_rate_hz)
    if _header(p) != ANNOTATED_HEADER:
        raise ValueError(f"{p} (line 1): header {_header(p)}, expected {', '.join(ANNOTATED_HEADER)}")
    data = _numeric(p, range(1, 8))
    with p.open(encoding="utf-8", newline="") as f:
        labels = np.array([row[0].strip() for row in list(csv.reader(f))[1:] if row])
    if labels.shape[0] != data.shape[0]:
        raise ValueError(f"{p}: {labels.shape[0]} part labels for {data.shape[0]} rows")
    order = np.argsort(data[:, 0], kind="stable")
    idx = data[order, 0]
    if not np.array_equal(idx, np.arange(idx.shape[0])):
        raise ValueError(f"{p}: column 'samples' is not a permutation of 0…{idx.shape[0] - 1}")
    data, labels = data[order], labels[order]
    parts: dict[str, tuple[int, int]] = {}
    for label in dict.fromkeys(labels.tolist()):
        where = np.flatnonzero(labels == label)
        if where[-1] - where[0] + 1 != where.shape[0]:
            raise ValueError(f"{p}: part {label!r} is not one contiguous run of samples")
        parts[label] = (int(where[0]), int(where[-1]))
    t = data[:, 0] / sample_rate_hz
    acc = data[:, 1:4]
    gyro = data[:, 4:7]
    sidecar = Sidecar(
        unit_serial="unknown",
        unit_model="MaD-Lab FAU 6-DOF unit (not named in the source)",
        channel_unit="count",
        sample_rate_hz=sample_rate_hz,
        g_local_m_s2=g_local_m_s2,
        procedure="ferraris-6+3",
        segments=_segments(p, parts, t, acc),
        extra={
            "source": {
                **_SOURCE,
                "files": [p.name],
                "time_note": "the parts were cut from a longer session and concatenated; "
                "time runs on across the cuts",
            },
            "extra_column_units": {"gyr_x_counts": "count", "gyr_y_counts": "count", "gyr_z_counts": "count"},
        },
    )
    extra_cols = {f"gyr_{a}_counts": _count_text(gyro[:, i]) for i, a in enumerate("xyz")}
    return Recording(
        sidecar=sidecar, t_s=t, accel_raw=np.ascontiguousarray(acc), extra_columns=extra_cols, source=str(p)
    )


def read_imucal(
    paths: Sequence[str | Path], sample_rate_hz: float, g_local_m_s2: float = G_LOCAL_M_S2
) -> Recording:
    """Read either imucal layout, told apart by the CSV header.

    :param paths: ``[session.csv, sections.json]`` (the JSON may be left out when it sits
        beside the CSV as ``<stem>_list.json``), or ``[annotated_session.csv]``.
    """
    if not paths:
        raise ValueError("no source file given")
    p = Path(paths[0])
    header = _header(p)
    if header == ANNOTATED_HEADER:
        if len(paths) > 1:
            raise ValueError(f"{p}: an annotated session carries its parts; give no second file")
        return read_imucal_annotated(p, sample_rate_hz, g_local_m_s2)
    if header == SESSION_HEADER:
        if len(paths) > 2:
            raise ValueError("expected the session CSV and its section-list JSON, no more")
        sections = Path(paths[1]) if len(paths) == 2 else p.with_name(f"{p.stem}_list.json")
        if not sections.is_file():
            raise ValueError(f"{p}: section list {sections} not found; give it as the second file")
        return read_imucal_session(p, sections, sample_rate_hz, g_local_m_s2)
    raise ValueError(
        f"{p} (line 1): header {header} is neither imucal layout "
        f"({', '.join(SESSION_HEADER)} / {', '.join(ANNOTATED_HEADER)})"
    )
