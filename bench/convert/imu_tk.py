"""IMU-TK's Xsens MTi test recording -> calbench-recording/1.

Source (``shared/data/real/imu_tk-xsens/README.md``): IMU-TK (Tedaldi, Pretto, Menegatti,
ICRA 2014) ships ``xsens_acc.mat`` and ``xsens_gyro.mat``, which despite the name are
whitespace-separated ASCII, ``t[s] x y z`` per line, in raw 16-bit ADC counts; or the same
data joined on time as ``xsens_mti_raw_counts.csv`` (``t_s, acc_{x,y,z}_counts,
gyr_{x,y,z}_counts``).

The unit was turned by hand between still poses on no table, so the recording has no
``table`` and no segments (static windows are found in the data). Counts stay counts:
``channel_unit`` is ``count``. The gyro channels are counts too, which the format's
``gyro_unit`` (rad/s or deg/s) cannot state, so they are kept as the extra columns
``gyr_x_counts`` … with their unit recorded in the sidecar. Every sample is kept.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from bench.recording.model import Recording, Sidecar

SAMPLE_RATE_HZ = 100.0
"""Nominal rate (the README: dt mean 9.999 ms)."""
G_LOCAL_M_S2 = 9.81744
"""Local gravity used by the IMU-TK authors (``apps/test_imu_calib.cpp``)."""
GYRO_EXTRA = ("gyr_x_counts", "gyr_y_counts", "gyr_z_counts")
_CSV_HEADER = ["t_s", "acc_x_counts", "acc_y_counts", "acc_z_counts", *GYRO_EXTRA]


def _load_ascii(path: Path) -> np.ndarray:
    try:
        data = np.loadtxt(path, comments=None, ndmin=2, dtype=float)
    except ValueError as exc:
        raise ValueError(f"{path}: not IMU-TK whitespace-separated 't x y z' text: {exc}") from None
    if data.shape[1] != 4:
        raise ValueError(f"{path}: {data.shape[1]} columns per line, expected 4 (t[s] x y z)")
    return data


def _load_joined_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    with path.open(encoding="utf-8", newline="") as f:
        header = next(csv.reader(f), [])
    if [h.strip() for h in header] != _CSV_HEADER:
        raise ValueError(f"{path} (line 1): header {header}, expected {', '.join(_CSV_HEADER)}")
    try:
        data = np.loadtxt(path, delimiter=",", skiprows=1, comments=None, ndmin=2, dtype=float)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return data[:, :4], np.column_stack([data[:, 0], data[:, 4:7]])


def _check(path: Path, data: np.ndarray) -> None:
    finite = np.all(np.isfinite(data), axis=1)
    if not np.all(finite):
        row = int(np.argmin(finite)) + 1
        raise ValueError(f"{path} (data row {row}): non-finite value; expected numbers")
    bad = np.flatnonzero(np.diff(data[:, 0]) <= 0)
    if bad.size:
        raise ValueError(f"{path} (data row {int(bad[0]) + 2}): time does not increase")


def _count_text(values: np.ndarray) -> list[str]:
    """Counts as written by the source: integers without a decimal point when integral."""
    if np.all(values == np.round(values)) and np.all(np.abs(values) < 2**53):
        return [str(v) for v in values.astype(np.int64).tolist()]
    return [repr(v) for v in values.tolist()]


def read_imu_tk(acc_path: str | Path, gyro_path: str | Path | None = None) -> Recording:
    """Read IMU-TK's Xsens recording.

    :param acc_path: ``xsens_acc.mat`` (ASCII ``t ax ay az``), or the joined
        ``xsens_mti_raw_counts.csv`` (then ``gyro_path`` must be ``None``).
    :param gyro_path: ``xsens_gyro.mat`` (ASCII ``t gx gy gz``), optional; its time column
        must equal the accelerometer's sample for sample.
    :returns: a hand-held :class:`Recording` in counts, gyro counts as extra columns.
    :raises ValueError: unreadable file, non-finite values, time not increasing, or
        accelerometer and gyro files that do not share their time stamps.
    """
    acc_p = Path(acc_path)
    gyro: np.ndarray | None
    if acc_p.suffix.lower() == ".csv":
        if gyro_path is not None:
            raise ValueError(f"{acc_p}: the joined CSV already holds the gyro; give no second file")
        acc, gyro = _load_joined_csv(acc_p)
        sources = [acc_p.name]
        gyro_p = acc_p
    else:
        acc = _load_ascii(acc_p)
        gyro_p = Path(gyro_path) if gyro_path is not None else acc_p
        gyro = _load_ascii(gyro_p) if gyro_path is not None else None
        sources = [acc_p.name] + ([gyro_p.name] if gyro_path is not None else [])
    _check(acc_p, acc)
    if gyro is not None:
        _check(gyro_p, gyro)
        if gyro.shape[0] != acc.shape[0] or not np.array_equal(gyro[:, 0], acc[:, 0]):
            n = min(gyro.shape[0], acc.shape[0])
            diff = np.flatnonzero(gyro[:n, 0] != acc[:n, 0])
            where = (
                f"first differing row {int(diff[0]) + 1}"
                if diff.size
                else f"{gyro.shape[0]} vs {acc.shape[0]} rows"
            )
            raise ValueError(
                f"{gyro_p}: time stamps differ from {acc_p.name} ({where}); expected the same samples"
            )
    extra: dict[str, object] = {
        "source": {
            "dataset": "IMU-TK test data (Tedaldi, Pretto, Menegatti, ICRA 2014), Xsens MTi",
            "files": sources,
            "repository": "Kyle-ak/imu_tk@7780270fb9a227c79323199303f23989e689a89d bin/test_data",
            "licence": "BSD-2-Clause",
            "protocol": "hand-held: ~50 s initial rest, then hand-placed still poses of 3-11 s; "
            "orientations unknown and not axis-aligned",
            "g_local_note": "9.81744 m/s² as used by the IMU-TK authors",
        },
    }
    extra_cols: dict[str, list[str]] = {}
    if gyro is not None:
        extra["extra_column_units"] = dict.fromkeys(GYRO_EXTRA, "count")
        extra_cols = {name: _count_text(gyro[:, i + 1]) for i, name in enumerate(GYRO_EXTRA)}
    sidecar = Sidecar(
        unit_serial="unknown",
        unit_model="Xsens MTi",
        channel_unit="count",
        sample_rate_hz=SAMPLE_RATE_HZ,
        g_local_m_s2=G_LOCAL_M_S2,
        procedure="hand-multi-position",
        extra=extra,
    )
    return Recording(
        sidecar=sidecar,
        t_s=np.ascontiguousarray(acc[:, 0]),
        accel_raw=np.ascontiguousarray(acc[:, 1:4]),
        extra_columns=extra_cols,
        source=str(acc_p),
    )
