"""Static windows of a recording: from its segments, or found in the data, and their statistics.

Detection (:func:`detect_static_windows`) marks a sample static when

* the moving standard deviation of the raw accelerometer channels over a centred window
  of ``window_s``, combined as s = sqrt(σ_x² + σ_y² + σ_z²) (the variance norm of
  IMU-TK's ``staticIntervalsDetector``, Tedaldi et al., ICRA 2014), is at most
  ``max_std``; by default ``max_std = std_factor × s_quiet`` where s_quiet is the 5th
  percentile of s over the recording (the quietest windows), and
* with a table, every encoder moves slower than ``max_table_rate_rad_s``, judged by the
  largest |Δθ|/Δt between consecutive samples inside the same centred window (a turn of
  the outer, vertical axis leaves gravity unchanged and only the encoders see it).

Runs of static samples closer than ``merge_gap_s`` whose mean raw reading differs by less
than ``max_std`` and whose table angles stay within ``max_angle_step_rad`` together are
merged; a run whose table angles drift by more than ``max_angle_step_rad`` is split. Each
run loses ``trim_s`` at both ends and is kept if it still lasts ``min_duration_s``.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt
from scipy.ndimage import maximum_filter1d

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class StaticWindow:
    """One static window: samples ``start:stop`` of the recording.

    :param start: first sample index.
    :param stop: one past the last sample index.
    :param start_s: time of the first sample (s).
    :param end_s: time of the last sample (s).
    :param label: segment label, or ``w01``, ``w02`` … for detected windows.
    :param nominal_up: sensor axis meant to point up (``"+x"`` … ``"-z"``) or ``None``.
    """

    start: int
    stop: int
    start_s: float
    end_s: float
    label: str = ""
    nominal_up: str | None = None

    @property
    def slice(self) -> slice:
        """``slice(start, stop)``."""
        return slice(self.start, self.stop)


class SegmentLike(Protocol):
    """Anything with the fields of a recording segment."""

    @property
    def start_s(self) -> float: ...
    @property
    def end_s(self) -> float: ...
    @property
    def label(self) -> str: ...
    @property
    def nominal_up(self) -> str | None: ...


@dataclass(frozen=True)
class WindowStats:
    """Per-window statistics of m windows.

    :param n: (m,) samples per window.
    :param mean: (m, 3) mean raw accelerometer reading (channel unit).
    :param std: (m, 3) sample standard deviation (ddof = 1) of the raw reading.
    :param table_mean_rad: (m, k) circular mean of each encoder angle, in (−π, π], or ``None``.
    :param temp_mean_c: (m,) mean temperature (°C, NaN samples ignored) or ``None``.
    :param mid_s: (m,) mid time of each window, (t_first + t_last)/2 (s).
    """

    n: npt.NDArray[np.int64]
    mean: FloatArray
    std: FloatArray
    table_mean_rad: FloatArray | None
    temp_mean_c: FloatArray | None
    mid_s: FloatArray


def _check_inputs(
    t_s: npt.ArrayLike, accel: npt.ArrayLike, table_rad: npt.ArrayLike | None
) -> tuple[FloatArray, FloatArray, FloatArray | None]:
    t = np.asarray(t_s, dtype=float).reshape(-1)
    a = np.asarray(accel, dtype=float)
    n = t.shape[0]
    if a.shape != (n, 3):
        raise ValueError(f"accel has shape {a.shape}, expected ({n}, 3) to match t_s")
    if n < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("t_s must be finite and strictly increasing, with at least 2 samples")
    if not np.all(np.isfinite(a)):
        raise ValueError(
            f"accel has non-finite values (first at sample {int(np.argmin(np.isfinite(a).all(1)))})"
        )
    q = None
    if table_rad is not None:
        q = np.asarray(table_rad, dtype=float)
        q = q[:, None] if q.ndim == 1 else q
        if q.ndim != 2 or q.shape[0] != n:
            raise ValueError(f"table_rad has shape {q.shape}, expected ({n}, k)")
        if not np.all(np.isfinite(q)):
            raise ValueError("table_rad has non-finite values")
    return t, a, q


def _moving_std_norm(a: FloatArray, w: int) -> FloatArray:
    """sqrt(Σ_c var_c) over a centred window of w samples (edges use the first/last full window)."""
    x = a - np.median(a, axis=0)
    c1 = np.vstack([np.zeros(3), np.cumsum(x, axis=0)])
    c2 = np.vstack([np.zeros(3), np.cumsum(x * x, axis=0)])
    s1 = c1[w:] - c1[:-w]
    s2 = c2[w:] - c2[:-w]
    var = np.clip((s2 - s1 * s1 / w) / (w - 1), 0.0, None).sum(axis=1)
    full = np.sqrt(var)  # value for windows starting at 0 … n-w
    lead = w // 2
    out = np.empty(a.shape[0])
    out[lead : lead + full.size] = full
    out[:lead] = full[0]
    out[lead + full.size :] = full[-1]
    return out


def _runs(mask: npt.NDArray[np.bool_]) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def _split_on_drift(runs: list[tuple[int, int]], q: FloatArray, max_step: float) -> list[tuple[int, int]]:
    out = []
    for s, e in runs:
        i = s
        while i < e:
            dev = np.max(np.abs(q[i:e] - q[i]), axis=1)
            j = i + int(np.argmax(dev > max_step)) if np.any(dev > max_step) else e
            out.append((i, j))
            i = j
    return out


def detect_static_windows(
    t_s: npt.ArrayLike,
    accel: npt.ArrayLike,
    table_rad: npt.ArrayLike | None = None,
    *,
    window_s: float = 0.5,
    max_std: float | None = None,
    std_factor: float = 3.0,
    max_table_rate_rad_s: float = 2e-3,
    max_angle_step_rad: float = 2e-3,
    min_duration_s: float = 1.0,
    trim_s: float = 0.25,
    merge_gap_s: float = 0.2,
) -> list[StaticWindow]:
    """Find the windows where the sensor (and table) held still.

    :param t_s: (n,) time stamps (s), strictly increasing.
    :param accel: (n, 3) raw accelerometer channels (any unit; ``max_std`` in that unit).
    :param table_rad: (n, k) encoder angles (rad, wrapped or not) or ``None`` (hand-held).
    :param window_s: length of the moving window for the variance and rate tests (s).
    :param max_std: threshold on sqrt(σ_x² + σ_y² + σ_z²) (channel unit); default
        ``std_factor`` × the 5th percentile of that statistic over the recording.
    :param std_factor: multiple of the quietest windows' scatter used when ``max_std`` is None.
    :param max_table_rate_rad_s: encoder rate above which the table is moving (rad/s).
    :param max_angle_step_rad: table-angle change that splits a run / prevents a merge (rad).
    :param min_duration_s: shortest window kept, after trimming (s).
    :param trim_s: removed at each end of a run (s).
    :param merge_gap_s: runs separated by less than this are merged if they agree (s).
    :returns: windows in time order, labelled ``w01``, ``w02``, …
    :raises ValueError: malformed input, or parameters out of range.
    """
    t, a, q = _check_inputs(t_s, accel, table_rad)
    for name, v in (
        ("window_s", window_s),
        ("std_factor", std_factor),
        ("min_duration_s", min_duration_s),
        ("max_table_rate_rad_s", max_table_rate_rad_s),
        ("max_angle_step_rad", max_angle_step_rad),
    ):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive number, got {v}")
    if not (np.isfinite(trim_s) and trim_s >= 0 and np.isfinite(merge_gap_s) and merge_gap_s >= 0):
        raise ValueError(f"trim_s and merge_gap_s must be >= 0, got {trim_s}, {merge_gap_s}")
    dt = float(np.median(np.diff(t)))
    w = max(5, round(window_s / dt))
    if t.shape[0] < 2 * w:
        raise ValueError(
            f"recording too short: {t.shape[0]} samples, need at least {2 * w} for window_s={window_s}"
        )
    score = _moving_std_norm(a, w)
    if max_std is None:
        quiet = float(np.percentile(score, 5.0))
        if quiet <= 0.0:  # quantised, perfectly constant windows: fall back to the smallest non-zero scatter
            positive = score[score > 0]
            quiet = float(positive.min()) if positive.size else np.finfo(float).tiny
        max_std = std_factor * quiet
    elif not (np.isfinite(max_std) and max_std > 0):
        raise ValueError(f"max_std must be a positive number, got {max_std}")
    mask = score <= max_std
    qu = None
    if q is not None:
        qu = np.unwrap(q, axis=0)
        rate = np.max(np.abs(np.diff(qu, axis=0)), axis=1) / np.diff(t)
        rate = np.concatenate([rate[:1], np.maximum(rate[1:], rate[:-1]), rate[-1:]])  # both neighbours
        mask &= maximum_filter1d(rate, size=w, mode="nearest") <= max_table_rate_rad_s
    runs = _runs(mask)
    if qu is not None:
        runs = _split_on_drift(runs, qu, max_angle_step_rad)
    merged: list[tuple[int, int]] = []
    for s, e in runs:
        if merged:
            ps, pe = merged[-1]
            gap = t[s] - t[pe - 1]
            same = np.linalg.norm(a[ps:pe].mean(0) - a[s:e].mean(0)) <= max_std
            if qu is not None:
                same = same and np.max(np.ptp(qu[ps:e], axis=0)) <= max_angle_step_rad
            if gap <= merge_gap_s + dt / 2 and same:
                merged[-1] = (ps, e)
                continue
        merged.append((s, e))
    out: list[StaticWindow] = []
    for s, e in merged:
        s2 = int(np.searchsorted(t, t[s] + trim_s, side="left"))
        e2 = int(np.searchsorted(t, t[e - 1] - trim_s, side="right"))
        if e2 - s2 >= 2 and t[e2 - 1] - t[s2] >= min_duration_s:
            out.append(StaticWindow(s2, e2, float(t[s2]), float(t[e2 - 1]), f"w{len(out) + 1:02d}"))
    return out


def windows_from_segments(t_s: npt.ArrayLike, segments: Sequence[SegmentLike]) -> list[StaticWindow]:
    """Static windows from a recording's segments: the samples with start_s <= t <= end_s.

    :raises ValueError: a segment holds fewer than 2 samples, or segments overlap.
    """
    t = np.asarray(t_s, dtype=float).reshape(-1)
    out = []
    for seg in segments:
        s = int(np.searchsorted(t, seg.start_s, side="left"))
        e = int(np.searchsorted(t, seg.end_s, side="right"))
        if e - s < 2:
            raise ValueError(
                f"segment {seg.label!r} [{seg.start_s}, {seg.end_s}] s holds {max(e - s, 0)} samples; "
                "expected at least 2"
            )
        out.append(StaticWindow(s, e, float(t[s]), float(t[e - 1]), seg.label, seg.nominal_up))
    out.sort(key=lambda w: w.start)
    for p, n in itertools.pairwise(out):
        if n.start < p.stop:
            raise ValueError(f"segments {p.label!r} and {n.label!r} overlap")
    return out


def window_stats(
    t_s: npt.ArrayLike,
    accel: npt.ArrayLike,
    table_rad: npt.ArrayLike | None,
    temp_c: npt.ArrayLike | None,
    windows: Sequence[StaticWindow],
) -> WindowStats:
    """Statistics of each window (see :class:`WindowStats`).

    Table angles are averaged on the circle, atan2(mean sin θ, mean cos θ), so a window
    at ±180° (where the encoder wraps) averages to ±180°, not 0.
    """
    t, a, q = _check_inputs(t_s, accel, table_rad)
    if not windows:
        raise ValueError("no windows")
    temp = None if temp_c is None else np.asarray(temp_c, dtype=float).reshape(-1)
    if temp is not None and temp.shape != t.shape:
        raise ValueError(f"temp_c has shape {temp.shape}, expected {t.shape}")
    for w in windows:
        if not (w.start >= 0 and w.start + 2 <= w.stop <= t.shape[0]):
            raise ValueError(
                f"window {w.label!r} [{w.start}:{w.stop}] is not within 0:{t.shape[0]} with >= 2 samples"
            )
    n = np.array([w.stop - w.start for w in windows], dtype=np.int64)
    mean = np.array([a[w.slice].mean(axis=0) for w in windows])
    std = np.array([a[w.slice].std(axis=0, ddof=1) for w in windows])
    tm = None
    if q is not None:
        tm = np.array([np.arctan2(np.sin(q[w.slice]).mean(0), np.cos(q[w.slice]).mean(0)) for w in windows])
    temp_mean = None
    if temp is not None:
        temp_mean = np.array(
            [np.nanmean(temp[w.slice]) if np.any(np.isfinite(temp[w.slice])) else np.nan for w in windows]
        )
    mid = np.array([(t[w.start] + t[w.stop - 1]) / 2 for w in windows])
    return WindowStats(n=n, mean=mean, std=std, table_mean_rad=tm, temp_mean_c=temp_mean, mid_s=mid)
