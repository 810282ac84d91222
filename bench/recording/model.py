"""In-memory form of a calbench-recording/1 run (CSV samples + JSON sidecar).

See ``docs/recording-format.md``. Everything here is plain frozen data; reading,
writing and validation live in ``reader.py`` / ``writer.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

FORMAT_ID = "calbench-recording/1"
CHANNEL_UNITS = ("V", "count", "m/s2", "g")
GYRO_UNITS = ("rad/s", "deg/s")
G0_M_S2 = 9.80665
"""Standard gravity (m/s²), the unit ``g`` of ``channel_unit``."""

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class TableAxis:
    """One table axis: a name and its unit rotation axis in the parent frame at zero angles."""

    name: str
    axis: tuple[float, float, float]


@dataclass(frozen=True)
class TableGeometry:
    """What the bench believes about its table.

    :param axes: outermost first.
    :param mount_rotation: (3, 3) rotation from the sensor's nominal frame to the innermost
        table frame.
    :param lever_arm_m: (3,) sensor reference point in the innermost table frame (m).
    :param encoder_resolution_deg: the step in which the encoders read (deg), or ``None``
        (not declared): the servo holds each pose anywhere within half a step of the reading.
    """

    axes: tuple[TableAxis, ...]
    mount_rotation: tuple[tuple[float, float, float], ...] = (
        (1.0, 0.0, 0.0),
        (0.0, 1.0, 0.0),
        (0.0, 0.0, 1.0),
    )
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    encoder_resolution_deg: float | None = None

    @property
    def axis_vectors(self) -> FloatArray:
        """(n_axes, 3) unit axis vectors."""
        return np.array([a.axis for a in self.axes], dtype=float)

    @property
    def mount_matrix(self) -> FloatArray:
        """(3, 3) mount rotation M."""
        return np.array(self.mount_rotation, dtype=float)


@dataclass(frozen=True)
class Segment:
    """A window the bench held still, or one motion profile.

    :param start_s: start time (s, same clock as ``t``).
    :param end_s: end time (s).
    :param label: free text, e.g. ``pos01``.
    :param nominal_up: for recordings without a table, the sensor axis meant to point up
        (``"+x"`` … ``"-z"``), else ``None``.
    """

    start_s: float
    end_s: float
    label: str = ""
    nominal_up: str | None = None


@dataclass(frozen=True)
class Sidecar:
    """The JSON sidecar: units, geometry, segments. Unknown keys are kept in ``extra``."""

    unit_serial: str
    channel_unit: str
    sample_rate_hz: float
    g_local_m_s2: float
    unit_model: str | None = None
    gyro_unit: str | None = None
    procedure: str | None = None
    table: TableGeometry | None = None
    segments: tuple[Segment, ...] | None = None
    extra: dict[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class Recording:
    """One run's samples and sidecar.

    :param sidecar: the sidecar.
    :param t_s: (n,) DAQ time stamps, strictly increasing (s).
    :param accel_raw: (n, 3) raw ax, ay, az in ``sidecar.channel_unit``.
    :param table_deg: (n, n_axes) encoder angles as read, possibly wrapped (deg), or
        ``None`` without a table. Use :meth:`table_rad_unwrapped` before differentiating.
    :param temp_c: (n,) sensor temperature (°C) or ``None``.
    :param gyro_raw: (n, 3) raw gyro channels in ``sidecar.gyro_unit`` or ``None``.
    :param extra_columns: unknown CSV columns, kept as read (name -> (n,) strings).
    :param source: path the recording was read from, for messages.
    """

    sidecar: Sidecar
    t_s: FloatArray
    accel_raw: FloatArray
    table_deg: FloatArray | None = None
    temp_c: FloatArray | None = None
    gyro_raw: FloatArray | None = None
    extra_columns: dict[str, list[str]] = field(default_factory=dict)
    source: str = ""

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.t_s.shape[0])

    def table_rad_unwrapped(self) -> FloatArray | None:
        """(n, n_axes) encoder angles in radians, unwrapped along time (:func:`unwrap_rad`)."""
        if self.table_deg is None:
            return None
        return unwrap_rad(np.deg2rad(self.table_deg))


UNWRAP_CHUNK = 1 << 16
"""Rows unwrapped at once by :func:`unwrap_rad`: its temporaries are (chunk, k), not (n, k)."""


def unwrap_rad(angles_rad: FloatArray) -> FloatArray:
    """``numpy.unwrap(angles_rad, axis=0)`` (period 2π), bit for bit, in place, chunk by chunk.

    numpy's rule: each step dd = p[i] − p[i−1] with |dd| ≥ π is replaced by its value in
    [−π, π) (+π for dd = π exactly), and the corrections are accumulated by a running sum,
    u[i] = p[i] + Σ_{j ≤ i} c_j. The running sum is continued across chunks from its last value,
    which repeats numpy's own sequence of additions, so the result is identical; numpy's
    version holds about six (n, k) temporaries at once.

    :param angles_rad: (n, k) wrapped angles (rad); overwritten by the result.
    :returns: ``angles_rad``, unwrapped.
    """
    u = angles_rad
    n = u.shape[0]
    if n < 2:
        return u
    carry = np.zeros((1, u.shape[1]))
    prev = u[:1].copy()
    for a in range(1, n, UNWRAP_CHUNK):
        p = u[a : a + UNWRAP_CHUNK].copy()
        dd = np.diff(np.concatenate([prev, p]), axis=0)
        ddmod = np.mod(dd + np.pi, 2.0 * np.pi) - np.pi
        np.copyto(ddmod, np.pi, where=(ddmod == -np.pi) & (dd > 0))
        correction = ddmod - dd
        np.copyto(correction, 0.0, where=np.abs(dd) < np.pi)
        running = np.cumsum(np.concatenate([carry, correction]), axis=0)[1:]
        u[a : a + UNWRAP_CHUNK] = p + running
        carry, prev = running[-1:], p[-1:]
    return u
