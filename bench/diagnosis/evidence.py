"""What a diagnosis of a static recording works from: window means, their noise, their poses.

Observations are stacked window-major: index 3·w + i is channel i of window w, so a
(m, 3) array ``a`` becomes ``a.reshape(-1)`` and back with ``reshape(m, 3)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.dynamic_model import G0_M_S2

__all__ = ["G0_M_S2", "FloatArray", "StaticEvidence"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class StaticEvidence:
    """Static windows of one recording, reduced to what the model is compared with.

    :param y: (m, 3) window means of the raw channels (channel units).
    :param V: (m, 3, 3) covariance of each window mean from its own samples (channel units²).
    :param f_m_s2: (m, 3) specific force the recording says each window saw (sensor frame, m/s²).
    :param mid_s: (m,) mid time of each window since the start of the recording (s).
    :param labels: window labels.
    :param g_local_m_s2: local gravity (m/s²).
    :param temp_c: (m,) mean sensor temperature per window (°C) or ``None``.
    :param table_rad: (m, k) circular-mean encoder angle per window (rad) or ``None``.
    :param axis_vectors: (k, 3) table axes, outermost first, or ``None``.
    :param mount: (3, 3) mount rotation (sensor nominal frame -> innermost table frame).
    :param orientation_known: ``False`` when f comes from the data itself (no table, no
        labelled poses): then only the magnitude of each window's reading is evidence.
    :param peak_rate_rad_s: largest table rate seen between the windows (rad/s), 0 if none.
    :param window_samples: per window (n_w, 3) raw samples, for within-window tests, or ``None``.
    :param sample_rate_hz: sampling rate (Hz), with ``window_samples``.
    :param window_temp_c: per window (n_w,) sensor temperature of each sample (°C, NaN where
        not measured), or ``None``: what a term in temperature does within a window
        (``within_window``).
    :param window_t_s: per window (n_w,) time of each sample (s, on the clock of ``mid_s``),
        or ``None``.
    :param last_move_sign: (m, k) sign of each table axis's last move before each window (0:
        it had not moved), or ``None`` (``hysteresis``).
    :param encoder_resolution_deg: the step in which the encoders read (deg; the sidecar's
        ``table.encoder_resolution_deg``), or ``None``: the readings taken as exact
        (``pose_quantisation``).
    :param run_t_s: (n,) time of every sample of the recording (s, the clock of ``mid_s``), with
        ``run_temp_c``, or ``None``.
    :param run_temp_c: (n,) sensor temperature of every sample, between the windows too (°C;
        gaps filled by linear interpolation), or ``None``: the history a thermal lag needs
        (``effects.thermal_lag``).
    :param window_bounds: (m, 2) each window's first sample and one past its last in the run's
        columns, with ``run_t_s``, or ``None``.
    """

    y: FloatArray
    V: FloatArray
    f_m_s2: FloatArray
    mid_s: FloatArray
    labels: tuple[str, ...]
    g_local_m_s2: float
    temp_c: FloatArray | None = None
    table_rad: FloatArray | None = None
    axis_vectors: FloatArray | None = None
    mount: FloatArray | None = None
    orientation_known: bool = True
    peak_rate_rad_s: float = 0.0
    window_samples: tuple[FloatArray, ...] | None = None
    sample_rate_hz: float | None = None
    window_temp_c: tuple[FloatArray, ...] | None = None
    window_t_s: tuple[FloatArray, ...] | None = None
    last_move_sign: FloatArray | None = None
    encoder_resolution_deg: float | None = None
    run_t_s: FloatArray | None = None
    run_temp_c: FloatArray | None = None
    window_bounds: npt.NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        m = self.y.shape[0] if self.y.ndim == 2 else -1
        if self.y.shape != (m, 3) or self.V.shape != (m, 3, 3) or self.f_m_s2.shape != (m, 3):
            raise ValueError(
                f"evidence: expected y (m, 3), V (m, 3, 3), f (m, 3); "
                f"got {self.y.shape}, {self.V.shape}, {self.f_m_s2.shape}"
            )
        if self.mid_s.shape != (m,) or len(self.labels) != m:
            raise ValueError(f"evidence: mid_s and labels need {m} entries")
        for name in ("y", "V", "f_m_s2", "mid_s"):
            a = getattr(self, name)
            if not np.all(np.isfinite(a)):
                w = int(np.argwhere(~np.isfinite(a))[0, 0])
                raise ValueError(f"evidence: {name} of window {self.labels[w]!r} is not finite")
        if self.temp_c is not None and self.temp_c.shape != (m,):
            raise ValueError(f"evidence: temp_c has shape {self.temp_c.shape}, expected ({m},)")
        if self.table_rad is not None and (self.table_rad.ndim != 2 or self.table_rad.shape[0] != m):
            raise ValueError(f"evidence: table_rad has shape {self.table_rad.shape}, expected ({m}, k)")
        for name in ("window_temp_c", "window_t_s"):
            per = getattr(self, name)
            if per is not None and len(per) != m:
                raise ValueError(f"evidence: {name} has {len(per)} windows, expected {m}")
        if self.run_temp_c is not None:
            n = self.run_temp_c.shape
            wb = self.window_bounds
            if self.run_t_s is None or self.run_t_s.shape != n or not np.all(np.isfinite(self.run_temp_c)):
                raise ValueError("evidence: run_temp_c needs run_t_s of its shape and finite values")
            if wb is None or wb.shape != (m, 2) or np.any(wb[:, 1] <= wb[:, 0]) or np.any(wb[:, 1] > n[0]):
                raise ValueError(f"evidence: window_bounds needs ({m}, 2) non-empty ranges within the run")
        step = self.encoder_resolution_deg
        if step is not None and not (np.isfinite(step) and step > 0):
            raise ValueError(f"evidence: encoder_resolution_deg must be > 0, got {step!r}")
        if np.any(np.diagonal(self.V, axis1=1, axis2=2) <= 0):
            raise ValueError("evidence: every window mean needs a positive variance")

    @property
    def m(self) -> int:
        """Number of windows."""
        return int(self.y.shape[0])

    @property
    def n_obs(self) -> int:
        """Number of scalar observations, 3·m."""
        return 3 * self.m

    @property
    def has_table(self) -> bool:
        """The windows were recorded on a table with encoders (``table_rad`` known)."""
        return self.table_rad is not None

    @property
    def has_temperature(self) -> bool:
        """A usable temperature per window (finite everywhere)."""
        return self.temp_c is not None and bool(np.all(np.isfinite(self.temp_c)))

    def attitudes(self) -> FloatArray | None:
        """(m, 3, 3) sensor -> base rotations implied by ``f`` (known orientations only), from the table."""
        if self.table_rad is None or self.axis_vectors is None:
            return None
        from bench.kinematics import attitude

        M = np.eye(3) if self.mount is None else self.mount
        return attitude(self.axis_vectors, self.table_rad, M)
