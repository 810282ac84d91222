"""The JSON sidecar of calbench-recording/1: validation on read, serialisation on write.

``parse_sidecar(obj, path)`` turns the decoded JSON into a :class:`Sidecar` or raises a
:class:`RecordingError` naming the key; ``sidecar_to_dict`` is its inverse. Unknown
top-level keys go to ``Sidecar.extra`` unchanged; unknown keys inside ``unit`` and
``table`` and inside segment entries are kept under ``extra["unit"]``,
``extra["table"]`` and ``extra["segments"]`` (a list parallel to the segments) so that a
read–write round trip loses nothing.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.inputs import InputError, check_identifier_text, check_text
from bench.recording.errors import RecordingError
from bench.recording.model import (
    CHANNEL_UNITS,
    FORMAT_ID,
    GYRO_UNITS,
    Segment,
    Sidecar,
    TableAxis,
    TableGeometry,
)

NOMINAL_UP = ("+x", "-x", "+y", "-y", "+z", "-z")
MAX_TABLE_AXES = 6
"""Most table axes a sidecar may list (calibration tables have one to three)."""
UNIT_TOL = 1e-6
"""Tolerance on axis-vector length and on the orthonormality/determinant of ``mount_rotation``."""
MAX_ENCODER_RESOLUTION_DEG = 1.0
"""Coarsest encoder step ``table.encoder_resolution_deg`` may declare (deg): a calibration
table's encoders read to arc-seconds; a step beyond a degree is a unit mistake (counts, arc-minutes)."""

_TOP_KEYS = {
    "format",
    "unit",
    "channel_unit",
    "gyro_unit",
    "sample_rate_hz",
    "g_local_m_s2",
    "procedure",
    "table",
    "segments",
}
_UNIT_KEYS = {"serial", "model"}
_TABLE_KEYS = {"axes", "mount_rotation", "lever_arm_m", "encoder_resolution_deg"}
_SEGMENT_KEYS = {"start_s", "end_s", "label", "nominal_up"}


def _short(value: Any, n: int = 60) -> str:
    """``repr`` of a value, cut to ``n`` characters (a message stays one readable line)."""
    r = repr(value)
    return r if len(r) <= n else r[:n] + "…"


def _number(value: Any, path: Path, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RecordingError(path, f"expected a number, got {_short(value)}", key=key)
    try:
        x = float(value)
    except OverflowError:
        raise RecordingError(path, f"integer {_short(value)} overflows a double", key=key) from None
    if not math.isfinite(x):
        raise RecordingError(path, f"expected a finite number, got {_short(value)}", key=key)
    return x


def _vector(value: Any, path: Path, key: str, n: int = 3) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != n:
        raise RecordingError(path, f"expected a list of {n} numbers, got {_short(value)}", key=key)
    return tuple(_number(v, path, f"{key}[{i}]") for i, v in enumerate(value))


def _text(value: Any, path: Path, key: str, *, identifier: bool = False) -> str:
    """A string under the text rules of :mod:`bench.inputs` (an identifier: also non-empty, trimmed)."""
    if not isinstance(value, str):
        raise RecordingError(path, f"expected a string, got {_short(value)}", key=key)
    try:
        return check_identifier_text(value, max_chars=200) if identifier else check_text(value)
    except InputError as exc:
        raise RecordingError(path, str(exc), key=key) from None


def _parse_table(obj: Any, path: Path, extra: dict[str, object]) -> TableGeometry:
    if not isinstance(obj, dict):
        raise RecordingError(path, f"expected an object with 'axes', got {_short(obj)}", key="table")
    if "axes" not in obj:
        raise RecordingError(
            path, "missing required key (one entry per table axis, outermost first)", key="table.axes"
        )
    axes_obj = obj["axes"]
    if not isinstance(axes_obj, list) or not axes_obj:
        raise RecordingError(
            path, f"expected a non-empty list of axes, got {_short(axes_obj)}", key="table.axes"
        )
    if len(axes_obj) > MAX_TABLE_AXES:
        raise RecordingError(
            path, f"{len(axes_obj)} table axes; expected at most {MAX_TABLE_AXES}", key="table.axes"
        )
    axes: list[TableAxis] = []
    for i, a in enumerate(axes_obj):
        key = f"table.axes[{i}]"
        if not isinstance(a, dict) or "axis" not in a:
            raise RecordingError(path, f"expected an object with 'name' and 'axis', got {_short(a)}", key=key)
        name = _text(a.get("name", f"axis{i + 1}"), path, f"{key}.name")
        u = _vector(a["axis"], path, f"{key}.axis")
        norm = math.sqrt(sum(c * c for c in u))
        if abs(norm - 1.0) > UNIT_TOL:
            raise RecordingError(
                path,
                f"axis vector {list(u)} has length {norm:.9g}; expected a unit "
                f"vector (|u| = 1 within {UNIT_TOL:g})",
                key=f"{key}.axis",
            )
        axes.append(TableAxis(name=name, axis=(u[0], u[1], u[2])))
    mount: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    if "mount_rotation" in obj:
        rows = obj["mount_rotation"]
        if not isinstance(rows, list) or len(rows) != 3:
            raise RecordingError(
                path,
                f"expected a 3x3 matrix (list of 3 rows), got {_short(rows)}",
                key="table.mount_rotation",
            )
        m = [_vector(r, path, f"table.mount_rotation[{i}]") for i, r in enumerate(rows)]
        M = np.array(m)
        ortho = float(np.max(np.abs(M.T @ M - np.eye(3))))
        det = float(np.linalg.det(M))
        if ortho > UNIT_TOL or abs(det - 1.0) > UNIT_TOL:
            raise RecordingError(
                path,
                f"not a rotation matrix: max |MᵀM − I| = {ortho:.3g}, det = {det:.9g}; "
                f"expected orthonormal with determinant +1 (tolerance {UNIT_TOL:g})",
                key="table.mount_rotation",
            )
        mount = tuple((r[0], r[1], r[2]) for r in m)
    lever = (0.0, 0.0, 0.0)
    if "lever_arm_m" in obj:
        v = _vector(obj["lever_arm_m"], path, "table.lever_arm_m")
        lever = (v[0], v[1], v[2])
    step = None
    if obj.get("encoder_resolution_deg") is not None:
        step = _number(obj["encoder_resolution_deg"], path, "table.encoder_resolution_deg")
        if not 0.0 < step <= MAX_ENCODER_RESOLUTION_DEG:
            raise RecordingError(
                path,
                f"encoder step {step:g}°; expected > 0 and at most {MAX_ENCODER_RESOLUTION_DEG:g}°",
                key="table.encoder_resolution_deg",
            )
    unknown = {k: v for k, v in obj.items() if k not in _TABLE_KEYS}
    if unknown:
        extra["table"] = unknown
    return TableGeometry(
        axes=tuple(axes), mount_rotation=mount, lever_arm_m=lever, encoder_resolution_deg=step
    )


def _parse_segments(obj: Any, path: Path, extra: dict[str, object]) -> tuple[Segment, ...]:
    if not isinstance(obj, list):
        raise RecordingError(path, f"expected a list of segments, got {_short(obj)}", key="segments")
    segs: list[Segment] = []
    unknown_per_segment: list[dict[str, Any]] = []
    for i, s in enumerate(obj):
        key = f"segments[{i}]"
        if not isinstance(s, dict):
            raise RecordingError(path, f"expected an object with start_s, end_s, got {_short(s)}", key=key)
        for k in ("start_s", "end_s"):
            if k not in s:
                raise RecordingError(path, "missing required key", key=f"{key}.{k}")
        start = _number(s["start_s"], path, f"{key}.start_s")
        end = _number(s["end_s"], path, f"{key}.end_s")
        if end <= start:
            raise RecordingError(path, f"end_s = {end} is not after start_s = {start}", key=key)
        label = _text(s.get("label", ""), path, f"{key}.label")
        up = s.get("nominal_up")
        if up is not None and up not in NOMINAL_UP:
            raise RecordingError(
                path,
                f"nominal_up {_short(up)} is not one of {', '.join(NOMINAL_UP)}",
                key=f"{key}.nominal_up",
            )
        segs.append(Segment(start_s=start, end_s=end, label=label, nominal_up=up))
        unknown_per_segment.append({k: v for k, v in s.items() if k not in _SEGMENT_KEYS})
    check_segments_disjoint(segs, path)
    if any(unknown_per_segment):
        extra["segments"] = unknown_per_segment
    return tuple(segs)


def check_segments_disjoint(segments: Sequence[Segment], path: str | Path) -> None:
    """Raise :class:`RecordingError` if two segments overlap (touching ends are allowed)."""
    order = sorted(range(len(segments)), key=lambda i: segments[i].start_s)
    for a, b in itertools.pairwise(order):
        if segments[b].start_s < segments[a].end_s:
            raise RecordingError(
                path,
                f"segments {segments[a].label or a!r} [{segments[a].start_s}, {segments[a].end_s}] s and "
                f"{segments[b].label or b!r} [{segments[b].start_s}, {segments[b].end_s}] s overlap; "
                "expected disjoint windows",
                key=f"segments[{b}]",
            )


def parse_sidecar(obj: Any, path: str | Path) -> Sidecar:
    """Validate a decoded sidecar and build a :class:`Sidecar`.

    :param obj: the decoded JSON value.
    :param path: the sidecar's path, for messages.
    :raises RecordingError: naming the key and what was expected.
    """
    p = Path(path)
    if not isinstance(obj, dict):
        raise RecordingError(p, "expected a JSON object at the top level")
    if "format" not in obj:
        raise RecordingError(p, f'missing required key; expected "{FORMAT_ID}"', key="format")
    if obj["format"] != FORMAT_ID:
        raise RecordingError(
            p, f'unknown format {_short(obj["format"])}; expected "{FORMAT_ID}"', key="format"
        )
    for k in ("unit", "channel_unit", "sample_rate_hz", "g_local_m_s2"):
        if k not in obj:
            raise RecordingError(p, "missing required key", key=k)
    unit = obj["unit"]
    if not isinstance(unit, dict):
        raise RecordingError(p, f"expected an object with 'serial', got {_short(unit)}", key="unit")
    if "serial" not in unit:
        raise RecordingError(
            p, "missing required key (serial number of the unit under test)", key="unit.serial"
        )
    serial = _text(unit["serial"], p, "unit.serial", identifier=True)
    model = unit.get("model")
    if model is not None:
        model = _text(model, p, "unit.model")
    extra: dict[str, object] = {k: v for k, v in obj.items() if k not in _TOP_KEYS}
    unit_unknown = {k: v for k, v in unit.items() if k not in _UNIT_KEYS}
    if unit_unknown:
        extra["unit"] = unit_unknown
    channel_unit = obj["channel_unit"]
    if channel_unit not in CHANNEL_UNITS:
        raise RecordingError(
            p,
            f"channel_unit {_short(channel_unit)} is not one of {', '.join(CHANNEL_UNITS)}",
            key="channel_unit",
        )
    gyro_unit = obj.get("gyro_unit")
    if gyro_unit is not None and gyro_unit not in GYRO_UNITS:
        raise RecordingError(
            p, f"gyro_unit {_short(gyro_unit)} is not one of {', '.join(GYRO_UNITS)}", key="gyro_unit"
        )
    rate = _number(obj["sample_rate_hz"], p, "sample_rate_hz")
    if rate <= 0:
        raise RecordingError(p, f"expected a positive sample rate (Hz), got {rate}", key="sample_rate_hz")
    g = _number(obj["g_local_m_s2"], p, "g_local_m_s2")
    if not 9.7 <= g <= 9.9:
        raise RecordingError(
            p,
            f"local gravity {g} m/s² is outside 9.7–9.9 m/s² (Earth's surface); expected m/s²",
            key="g_local_m_s2",
        )
    procedure = obj.get("procedure")
    if procedure is not None:
        procedure = _text(procedure, p, "procedure")
    table = _parse_table(obj["table"], p, extra) if obj.get("table") is not None else None
    segments = _parse_segments(obj["segments"], p, extra) if obj.get("segments") is not None else None
    return Sidecar(
        unit_serial=serial,
        channel_unit=channel_unit,
        sample_rate_hz=rate,
        g_local_m_s2=g,
        unit_model=model,
        gyro_unit=gyro_unit,
        procedure=procedure,
        table=table,
        segments=segments,
        extra=extra,
    )


def segment_to_dict(seg: Segment) -> dict[str, object]:
    """JSON form of one segment (``nominal_up`` only when set)."""
    d: dict[str, object] = {"start_s": seg.start_s, "end_s": seg.end_s, "label": seg.label}
    if seg.nominal_up is not None:
        d["nominal_up"] = seg.nominal_up
    return d


def sidecar_to_dict(sc: Sidecar) -> dict[str, object]:
    """JSON form of a sidecar, the inverse of :func:`parse_sidecar`."""
    extra = dict(sc.extra)
    unit: dict[str, object] = {"serial": sc.unit_serial}
    if sc.unit_model is not None:
        unit["model"] = sc.unit_model
    unit_extra = extra.pop("unit", None)
    if isinstance(unit_extra, dict):
        unit.update(unit_extra)
    d: dict[str, object] = {"format": FORMAT_ID, "unit": unit, "channel_unit": sc.channel_unit}
    if sc.gyro_unit is not None:
        d["gyro_unit"] = sc.gyro_unit
    d["sample_rate_hz"] = sc.sample_rate_hz
    d["g_local_m_s2"] = sc.g_local_m_s2
    if sc.procedure is not None:
        d["procedure"] = sc.procedure
    table_extra = extra.pop("table", None)
    if sc.table is not None:
        table: dict[str, object] = {
            "axes": [{"name": a.name, "axis": list(a.axis)} for a in sc.table.axes],
            "mount_rotation": [list(r) for r in sc.table.mount_rotation],
            "lever_arm_m": list(sc.table.lever_arm_m),
        }
        if sc.table.encoder_resolution_deg is not None:
            table["encoder_resolution_deg"] = sc.table.encoder_resolution_deg
        if isinstance(table_extra, dict):
            table.update(table_extra)
        d["table"] = table
    seg_extra = extra.pop("segments", None)
    if sc.segments is not None:
        segs = [segment_to_dict(s) for s in sc.segments]
        if isinstance(seg_extra, list) and len(seg_extra) == len(segs):
            for s, e in zip(segs, seg_extra, strict=True):
                if isinstance(e, dict):
                    s.update(e)
        d["segments"] = segs
    d.update(extra)
    return d
