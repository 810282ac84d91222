"""The stretch of a recording whose noise is analysed, and its samples in the unit the noise is told in.

Used by ``calbench allan`` and by ``calbench plan --noise-from``, so both read a unit's noise
from the same samples. The stretch is, in this order: the asked time window
(``window_s``, START ≤ t ≤ END), the whole file (``whole``), else the longest of the windows
the calibration holds still (``bench.calibration.windows.choose_windows``: the sidecar's
segments in which the table did not move, and without a table those with a ``nominal_up``
when any has one, so a hand-made turn between poses is never read as noise; or, without
segments, the static windows found in the data), else the whole file. Channels recorded in
``g`` are converted to m/s² (× ``G0_M_S2``); ``V`` and ``count`` stay in their own unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.calibration.windows import choose_windows
from bench.recording import G0_M_S2, Recording

FloatArray = npt.NDArray[np.float64]

MIN_STRETCH_SAMPLES = 3
"""Fewest samples an asked window, a segment or a detected window must hold to be the stretch."""


@dataclass(frozen=True)
class NoiseStretch:
    """Which samples are analysed and why.

    :param samples: [start, stop) of the recording's samples.
    :param source: where the stretch came from (``--window-s 10 70``, ``whole file``,
        ``longest segment LABEL``, ``longest static window found in the data``, …).
    """

    samples: slice
    source: str

    @property
    def n(self) -> int:
        """Samples in the stretch."""
        return int(self.samples.stop - self.samples.start)


@dataclass(frozen=True)
class NoiseChannels:
    """The accelerometer channels in the unit their noise is told in.

    :param unit: ``m/s2`` (also for a recording in ``g``), ``V`` or ``count``.
    :param data: (n, 3) samples in ``unit``.
    """

    unit: str
    data: FloatArray


def noise_channels(rec: Recording) -> NoiseChannels:
    """The recording's channels, in m/s² when recorded in ``g`` (module docstring)."""
    unit = rec.sidecar.channel_unit
    if unit == "g":
        return NoiseChannels("m/s2", np.asarray(rec.accel_raw * G0_M_S2, dtype=float))
    return NoiseChannels(unit, np.asarray(rec.accel_raw, dtype=float))


def select_noise_stretch(
    rec: Recording, window_s: tuple[float, float] | list[float] | None = None, *, whole: bool = False
) -> NoiseStretch:
    """The stretch to analyse (module docstring).

    :param window_s: (START, END) in the recording's time (s), or ``None``.
    :param whole: the whole file, when no window is asked.
    :raises ValueError: a window that is not finite START < END, or holds fewer than
        :data:`MIN_STRETCH_SAMPLES` samples (named with the recording's span).
    """
    t = rec.t_s
    if window_s is not None:
        start, end = window_s
        if not (math.isfinite(start) and math.isfinite(end) and start < end):
            raise ValueError(f"--window-s: need finite START < END, got {start} {end}")
        idx = np.flatnonzero((t >= start) & (t <= end))
        if idx.size < MIN_STRETCH_SAMPLES:
            raise ValueError(
                f"{rec.source}: --window-s {start:g} {end:g} holds {idx.size} samples "
                f"(recording spans {t[0]:g} to {t[-1]:g} s); need at least {MIN_STRETCH_SAMPLES}"
            )
        return NoiseStretch(slice(int(idx[0]), int(idx[-1]) + 1), f"--window-s {start:g} {end:g}")
    if whole:
        return NoiseStretch(slice(0, t.size), "whole file")
    try:
        windows = choose_windows(rec).used
    except ValueError:
        windows = ()
    if windows:
        w = max(windows, key=lambda w: w.stop - w.start)
        if w.stop - w.start >= MIN_STRETCH_SAMPLES:
            if rec.sidecar.segments:
                return NoiseStretch(w.slice, f"longest segment {w.label or '(unlabelled)'}")
            return NoiseStretch(w.slice, "longest static window found in the data")
    return NoiseStretch(slice(0, t.size), "whole file (no static window found)")
