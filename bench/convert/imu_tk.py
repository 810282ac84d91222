"""IMU-TK data files -> calbench-recording/1.

Source format: IMU-TK (Tedaldi, Pretto, Menegatti, ICRA 2014) reads whitespace-separated
ASCII ``t[s] x y z`` per line, one file for the accelerometer and one for the gyro (its own
test data names them ``xsens_acc.mat`` and ``xsens_gyro.mat``); or the two joined on time
as a CSV with the header ``t_s, acc_{x,y,z}_counts, gyr_{x,y,z}_counts`` (the Xsens data
set's ``xsens_mti_raw_counts.csv``, the data set's own README, docs/real-datasets.md).

What the files say, and so what is written: the time stamps (the sample rate is their
median spacing) and three numbers per sensor and sample, every sample kept. What they do
not say, and so must be given (the CLI asks for it, exit 2 naming the option): the unit of
the accelerometer channels (``channel_unit``), the unit of the gyro channels, local
gravity. What is written only when given: the unit's model and serial, and which data set
the files come from (no data set is credited by default). IMU-TK's method takes still
poses of a unit turned by hand, with no table: the recording has no ``table`` and no
segments (static windows are found in the data). Gyro channels in rad/s or deg/s become
the format's ``gx gy gz`` with ``gyro_unit``; in any other unit (counts, V) the extra
columns ``gyr_x_<unit>`` … with their unit in ``extra_column_units``.

The Xsens MTi data set shipped with IMU-TK is raw 16-bit counts for both sensors, local
gravity 9.81744 m/s² as used by its authors (``apps/test_imu_calib.cpp``).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from bench.recording.model import Recording, Sidecar

XSENS_G_LOCAL_M_S2 = 9.81744
"""Local gravity of IMU-TK's own Xsens data set (``apps/test_imu_calib.cpp``)."""
CHANNEL_UNITS = ("count", "V", "m/s2", "g")
"""Accelerometer units calbench-recording/1 accepts."""
GYRO_UNITS = ("rad/s", "deg/s", "count", "V")
"""Gyro units: the format's ``gyro_unit`` (rad/s, deg/s), or raw units kept as extra columns."""
_EXTRA_SUFFIX = {"count": "counts", "V": "V"}
_CSV_HEADER = [
    "t_s",
    "acc_x_counts",
    "acc_y_counts",
    "acc_z_counts",
    "gyr_x_counts",
    "gyr_y_counts",
    "gyr_z_counts",
]
MAGNITUDE_TOLERANCE = 0.5
"""A recording declared in m/s2 or g whose median |a| is off 1 g by more than this fraction is
refused: the declared unit cannot be the data's."""


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


def gyro_extra_names(gyro_unit: str) -> tuple[str, str, str]:
    """Names of the extra columns that keep gyro channels in a raw unit (``count``, ``V``)."""
    suffix = _EXTRA_SUFFIX[gyro_unit]
    return (f"gyr_x_{suffix}", f"gyr_y_{suffix}", f"gyr_z_{suffix}")


def _check_magnitude(path: Path, acc: np.ndarray, channel_unit: str, g: float) -> None:
    if channel_unit not in ("m/s2", "g"):
        return
    expect = g if channel_unit == "m/s2" else g / 9.80665
    med = float(np.median(np.linalg.norm(acc[:, 1:4], axis=1)))
    if abs(med / expect - 1.0) > MAGNITUDE_TOLERANCE:
        raise ValueError(
            f"{path}: median |a| is {med:.4g}, not near 1 g = {expect:.4g} {channel_unit}: "
            f"the data are not in {channel_unit}; give the unit they are in (--channel-unit)"
        )


def read_imu_tk(
    acc_path: str | Path,
    gyro_path: str | Path | None = None,
    *,
    channel_unit: str | None,
    g_local_m_s2: float,
    gyro_unit: str | None = None,
    unit_model: str | None = None,
    unit_serial: str = "unknown",
    dataset: str | None = None,
) -> Recording:
    """Read IMU-TK data files (module docstring).

    :param acc_path: accelerometer file (ASCII ``t ax ay az``), or the joined CSV (then
        ``gyro_path`` must be ``None``).
    :param gyro_path: gyro file (ASCII ``t gx gy gz``), optional; its time column must equal
        the accelerometer's sample for sample.
    :param channel_unit: unit of the accelerometer numbers, one of :data:`CHANNEL_UNITS`;
        ``None`` only for the joined CSV, whose header names counts.
    :param g_local_m_s2: local gravity where the data were taken (m/s²).
    :param gyro_unit: unit of the gyro numbers (:data:`GYRO_UNITS`), required with a gyro
        file (the joined CSV's header names counts).
    :param unit_model: the unit's model, written only when given.
    :param unit_serial: the unit's serial number (``unknown`` when not given).
    :param dataset: which data set the files come from (credit), written only when given.
    :returns: a hand-held :class:`Recording` (no table, no segments).
    :raises ValueError: unreadable file, non-finite values, time not increasing, files that
        do not share their time stamps, a unit outside the accepted ones, or a declared
        m/s2 or g unit that the data's magnitude contradicts.
    """
    if not (np.isfinite(g_local_m_s2) and 9.7 < g_local_m_s2 < 9.9):
        raise ValueError(f"local gravity {g_local_m_s2} m/s²: expected a value between 9.7 and 9.9")
    acc_p = Path(acc_path)
    gyro: np.ndarray | None
    if acc_p.suffix.lower() == ".csv":
        if gyro_path is not None:
            raise ValueError(f"{acc_p}: the joined CSV already holds the gyro; give no second file")
        for what, given in (("accelerometer", channel_unit), ("gyro", gyro_unit)):
            if given not in (None, "count"):
                raise ValueError(f"{acc_p} (line 1): the header names the {what} in counts, not {given}")
        channel_unit, gyro_unit = "count", "count"
        acc, gyro = _load_joined_csv(acc_p)
        sources = [acc_p.name]
        gyro_p = acc_p
    else:
        acc = _load_ascii(acc_p)
        gyro_p = Path(gyro_path) if gyro_path is not None else acc_p
        gyro = _load_ascii(gyro_p) if gyro_path is not None else None
        sources = [acc_p.name] + ([gyro_p.name] if gyro_path is not None else [])
    if channel_unit not in CHANNEL_UNITS:
        raise ValueError(
            f"{acc_p}: accelerometer unit {channel_unit!r}: the files do not say it; "
            f"expected one of {', '.join(CHANNEL_UNITS)}"
        )
    if gyro is not None and gyro_unit not in GYRO_UNITS:
        raise ValueError(
            f"{gyro_p}: gyro unit {gyro_unit!r}: the files do not say it; "
            f"expected one of {', '.join(GYRO_UNITS)}"
        )
    _check(acc_p, acc)
    if acc.shape[0] < 2:
        raise ValueError(f"{acc_p}: {acc.shape[0]} sample(s); expected at least 2")
    _check_magnitude(acc_p, acc, channel_unit, g_local_m_s2)
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
    source: dict[str, object] = {"format": "IMU-TK ASCII, t[s] x y z per line", "files": sources}
    if dataset is not None:
        source["dataset"] = dataset
    extra: dict[str, object] = {"source": source}
    extra_cols: dict[str, list[str]] = {}
    gyro_raw = None
    sidecar_gyro_unit = None
    if gyro is not None:
        assert gyro_unit is not None
        if gyro_unit in ("rad/s", "deg/s"):
            gyro_raw, sidecar_gyro_unit = np.ascontiguousarray(gyro[:, 1:4]), gyro_unit
        else:
            names = gyro_extra_names(gyro_unit)
            extra["extra_column_units"] = dict.fromkeys(names, gyro_unit)
            extra_cols = {name: _count_text(gyro[:, i + 1]) for i, name in enumerate(names)}
    dt = float(np.median(np.diff(acc[:, 0])))
    sidecar = Sidecar(
        unit_serial=unit_serial,
        unit_model=unit_model,
        channel_unit=channel_unit,
        gyro_unit=sidecar_gyro_unit,
        sample_rate_hz=float(f"{1.0 / dt:.6g}"),
        g_local_m_s2=float(g_local_m_s2),
        extra=extra,
    )
    return Recording(
        sidecar=sidecar,
        t_s=np.ascontiguousarray(acc[:, 0]),
        accel_raw=np.ascontiguousarray(acc[:, 1:4]),
        gyro_raw=gyro_raw,
        extra_columns=extra_cols,
        source=str(acc_p),
    )
