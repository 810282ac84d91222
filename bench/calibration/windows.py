"""The windows of a recording and what the bench believed about them: the one place where
static windows are chosen, averaged, and given the specific force they saw.

Used by the static and orientation-free calibration (``bench.calibration.static``), the
dynamic calibration's reference windows (``bench.calibration.dynamic``) and the diagnosis
glue (``bench.calibration.diagnose``), so all three read a recording the same way:

* windows: the sidecar's segments in which the table did not move (without a table, those
  labelled ``nominal_up`` when any segment is), or detected ones when there are no segments;
* window angles: the mean encoder angle of each window, taken relative to the window's
  first sample and wrapped to (−180°, 180°] before averaging (robust to the ±180° wrap);
* specific force per window: f_w = Rᵀ [0, 0, g] at those angles (``docs/recording-format.md``,
  "Kinematics"), or ±g along the ``nominal_up`` axis of a hand-placed window.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from bench.estimation.window_noise import WindowNoise, pooled_mean_covariances, window_noise
from bench.estimation.windows import StaticWindow, detect_static_windows, windows_from_segments
from bench.kinematics import attitude, static_specific_force
from bench.recording import Recording

if TYPE_CHECKING:
    from bench.estimation.motion_data import MotionData

FloatArray = npt.NDArray[np.float64]

MAX_TABLE_MOTION_RAD = 1e-3
"""A segment whose encoder angles span more than this is a motion, not a static window."""
MIN_WINDOW_SAMPLES = 8
"""Fewest samples a static window needs to be averaged with an honest noise estimate."""
NOMINAL_AXES: dict[str, tuple[int, float]] = {
    "+x": (0, 1.0),
    "-x": (0, -1.0),
    "+y": (1, 1.0),
    "-y": (1, -1.0),
    "+z": (2, 1.0),
    "-z": (2, -1.0),
}
"""``nominal_up`` label -> (sensor axis index, sign) of the axis meant to point up."""


def where(rec: Recording) -> str:
    """How error messages name the recording: its path, or ``"recording"``."""
    return rec.source or "recording"


def window_angles(table_deg: FloatArray, w: StaticWindow) -> tuple[FloatArray, FloatArray]:
    """Mean encoder angles (rad) of a window and their span (rad), robust to wrapping.

    :param table_deg: (n, k) encoder angles of the recording (deg, possibly wrapped).
    :param w: the window.
    :returns: (k,) mean angles (rad) and (k,) max − min span (rad). Angles are taken
        relative to the window's first sample and wrapped to (−180°, 180°] before averaging,
        so a window at the ±180° wrap averages correctly.
    """
    q = np.ascontiguousarray(table_deg[w.start : w.stop].T)  # (k, n): fast reductions along time
    d = (q - q[:, :1] + 180.0) % 360.0 - 180.0
    return np.deg2rad(q[:, 0] + d.mean(axis=1)), np.deg2rad(d.max(axis=1) - d.min(axis=1))


@dataclass(frozen=True)
class UnusedWindow:
    """A declared segment (or detected window) that the fit did not use, and why.

    :param label: segment label or detected-window name.
    :param start_s: first sample time (s); :param end_s: last sample time (s).
    :param n_samples: samples it holds.
    :param reason: why it was left out, one phrase.
    """

    label: str
    start_s: float
    end_s: float
    n_samples: int
    reason: str

    def to_contract(self) -> dict[str, Any]:
        """``{label, start_s, end_s, n_samples, reason}``."""
        return {
            "label": self.label,
            "start_s": self.start_s,
            "end_s": self.end_s,
            "n_samples": self.n_samples,
            "reason": self.reason,
        }


@dataclass(frozen=True)
class WindowSelection:
    """The windows a static or scalar fit uses, and the declared ones it does not."""

    used: tuple[StaticWindow, ...]
    unused: tuple[UnusedWindow, ...]


def choose_windows(rec: Recording) -> WindowSelection:
    """Static windows of a recording and the declared ones left out, each with its reason.

    Used: the sidecar's segments in which the table did not move (without a table and with
    any ``nominal_up``, those with one: the others are the motions between poses), or the
    detected windows when the sidecar has none; each with at least
    :data:`MIN_WINDOW_SAMPLES` samples (a window mean's noise needs them).

    :raises ValueError: no usable static window (the message names the ones left out).
    """
    unused: list[UnusedWindow] = []

    def leave(w: StaticWindow, reason: str) -> None:
        unused.append(UnusedWindow(w.label, w.start_s, w.end_s, w.stop - w.start, reason))

    if rec.sidecar.segments:
        wins = windows_from_segments(rec.t_s, rec.sidecar.segments)
        if rec.table_deg is not None:
            kept = []
            for w in wins:
                span = float(np.max(window_angles(rec.table_deg, w)[1]))
                if span <= MAX_TABLE_MOTION_RAD:
                    kept.append(w)
                else:
                    leave(
                        w,
                        f"the table moved {np.rad2deg(span):.3g}° during it (a static window "
                        f"allows {np.rad2deg(MAX_TABLE_MOTION_RAD):.2g}°): a motion, not a still window",
                    )
            wins = kept
        elif any(w.nominal_up is not None for w in wins):
            # a hand-held session names the pose of each static window; the others are motions
            for w in wins:
                if w.nominal_up is None:
                    leave(w, "no nominal_up while other segments have one: taken as a motion between poses")
            wins = [w for w in wins if w.nominal_up is not None]
    else:
        wins = detect_static_windows(rec.t_s, rec.accel_raw, rec.table_rad_unwrapped())
    for w in wins:
        if w.stop - w.start < MIN_WINDOW_SAMPLES:
            leave(
                w,
                f"{w.stop - w.start} samples, fewer than the {MIN_WINDOW_SAMPLES} a window mean's "
                "noise estimate needs",
            )
    wins = [w for w in wins if w.stop - w.start >= MIN_WINDOW_SAMPLES]
    unused.sort(key=lambda u: u.start_s)
    if not wins:
        named = "; ".join(f"{u.label!r}: {u.reason}" for u in unused)
        raise ValueError(
            f"{where(rec)}: no static window with at least {MIN_WINDOW_SAMPLES} samples"
            + (f" (left out: {named})" if named else "")
        )
    return WindowSelection(tuple(wins), tuple(unused))


def select_windows(rec: Recording) -> list[StaticWindow]:
    """The static windows :func:`choose_windows` uses.

    :raises ValueError: no usable static window.
    """
    return list(choose_windows(rec).used)


def unused_warning(unused: tuple[UnusedWindow, ...]) -> str | None:
    """One sentence naming the unused declared windows, or ``None`` if there are none."""
    if not unused:
        return None
    return f"{len(unused)} declared window(s) not used: " + "; ".join(
        f"{u.label!r} ({u.start_s:.3f}-{u.end_s:.3f} s): {u.reason}" for u in unused
    )


def window_means(rec: Recording, wins: list[StaticWindow]) -> tuple[FloatArray, FloatArray]:
    """(m, 3) window means of the raw outputs and (m, 3, 3) honest covariances of those means
    (batch means per window, correlation factor pooled over the run: ``window_noise``).

    :raises ValueError: a window whose noise cannot be estimated (named with its times).
    """
    noises: list[WindowNoise] = []
    for w in wins:
        try:
            noises.append(window_noise(rec.accel_raw[w.start : w.stop]))
        except ValueError as exc:
            raise ValueError(f"window {w.label!r} ({w.start_s:.3f}-{w.end_s:.3f} s): {exc}") from exc
    return np.array([q.mean for q in noises]), pooled_mean_covariances(noises)


def table_window_angles(rec: Recording, wins: list[StaticWindow]) -> FloatArray:
    """(m, k) mean encoder angles (rad) of each window (:func:`window_angles`).

    :raises ValueError: the recording has no table columns.
    """
    if rec.table_deg is None:
        raise ValueError(f"{where(rec)}: no table columns")
    return np.array([window_angles(rec.table_deg, w)[0] for w in wins])


def labelled_force(wins: list[StaticWindow], g_m_s2: float) -> FloatArray:
    """(m, 3) specific force (m/s²) of hand-placed windows: ±g along each ``nominal_up`` axis.

    :raises ValueError: a window without a ``nominal_up`` in :data:`NOMINAL_AXES`.
    """
    f = np.zeros((len(wins), 3))
    for k, w in enumerate(wins):
        if w.nominal_up not in NOMINAL_AXES:
            raise ValueError(f"segment {w.label!r} has no nominal_up in {sorted(NOMINAL_AXES)}")
        axis, sign = NOMINAL_AXES[str(w.nominal_up)]
        f[k, axis] = sign * g_m_s2
    return f


def known_specific_force(rec: Recording, wins: list[StaticWindow]) -> FloatArray | None:
    """(m, 3) specific force (m/s²) per window from the table or ``nominal_up``; ``None`` if unknown.

    With a table: f_w = Rᵀ [0, 0, g] at :func:`table_window_angles`. Without one, every
    window labelled: :func:`labelled_force`.

    :raises ValueError: a segment whose ``nominal_up`` is not one of :data:`NOMINAL_AXES`.
    """
    g = rec.sidecar.g_local_m_s2
    table = rec.sidecar.table
    if table is not None and rec.table_deg is not None:
        qm = table_window_angles(rec, wins)
        return static_specific_force(attitude(table.axis_vectors, qm, table.mount_matrix), g)
    if all(w.nominal_up in NOMINAL_AXES for w in wins):
        return labelled_force(wins, g)
    bad = [w.label for w in wins if w.nominal_up is not None and w.nominal_up not in NOMINAL_AXES]
    if bad:
        raise ValueError(f"{where(rec)}: segment(s) {bad} have a nominal_up outside {sorted(NOMINAL_AXES)}")
    return None


def moving_samples(rec: Recording) -> tuple[MotionData, FloatArray]:
    """The motion regressors and raw samples of a moving-table recording.

    :returns: ``motion_data.prepare_motion`` of the unwrapped encoder angles and the
        sidecar geometry, and the (n, 3) raw outputs (channel units).
    :raises ValueError: no table, or a raw sample that is not finite (named by row and time).
    """
    from bench.estimation.motion_data import prepare_motion  # scipy.signal: moving recordings only

    geo = rec.sidecar.table
    q = rec.table_rad_unwrapped()
    if geo is None or q is None:
        raise ValueError("a moving-table recording needs the table (sidecar 'table' and table_i columns)")
    y = np.asarray(rec.accel_raw, dtype=float)
    bad = np.argwhere(~np.isfinite(y))
    if bad.size:
        row, col = bad[0]
        raise ValueError(f"sample {row} (t = {rec.t_s[row]:.6g} s): {'xyz'[col]} channel is not finite")
    return prepare_motion(rec.t_s, q, geo.axis_vectors, geo.mount_matrix), y
