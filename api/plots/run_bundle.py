"""The plot series of a finished run, computed once per recording and kept in a small cache.

Fitting a recording costs far more than serving it, and a dashboard polls, so the series
of a run are cached by ``(run id, recording path, size, mtime)``: a recording rewritten
(a resumed run) is fitted again. One lock per key lets fifty readers of a fresh run wait
for one computation instead of starting fifty.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from api.plots.run_series import (
    PreviousCalibration,
    allan_series,
    g_check_series,
    pick_noise_span,
    residual_series,
)
from bench.calibration import CalibrationResult, calibrate_recording
from bench.recording import read_recording

CACHE_SIZE = 32


@dataclass(frozen=True)
class RunBundle:
    """What the run page plots, as JSON-able dicts.

    :param calibration: the fit (kept for 'before' variants of the |g| check).
    :param residuals: :func:`~api.plots.run_series.residual_series`.
    :param allan: :func:`~api.plots.run_series.allan_series`, or ``None`` with ``allan_error``.
    """

    calibration: CalibrationResult
    residuals: dict[str, Any]
    allan: dict[str, Any] | None
    allan_error: str | None

    def g_check(
        self,
        nominal_scale: float | None = None,
        nominal_bias: Sequence[float] | None = None,
        previous: PreviousCalibration | None = None,
    ) -> dict[str, Any]:
        """|g| before/after (see :func:`~api.plots.run_series.g_check_series`)."""
        return g_check_series(
            self.calibration, nominal_scale=nominal_scale, nominal_bias=nominal_bias, previous=previous
        )


def build_bundle(recording_path: str | Path, noise_windows: Sequence[tuple[float, float]]) -> RunBundle:
    """Read and fit a recording, and compute its series.

    :param noise_windows: (start_s, end_s) of the run's noise windows (may be empty).
    :raises OSError: the recording cannot be read. :raises ValueError: it is malformed or
        cannot be fitted (the message names the file).
    """
    rec = read_recording(recording_path)
    cal = calibrate_recording(rec)
    static = [(w.start_s, w.end_s) for w in cal.windows]
    allan: dict[str, Any] | None = None
    allan_error: str | None = None
    try:
        s, e, source = pick_noise_span(rec, noise_windows, static)
        allan = allan_series(rec, s, e, source)
    except ValueError as exc:
        allan_error = str(exc)
    return RunBundle(cal, residual_series(cal), allan, allan_error)


class BundleCache:
    """LRU cache of :class:`RunBundle` with one computation per key at a time."""

    def __init__(self, size: int = CACHE_SIZE) -> None:
        self.size = size
        self._items: OrderedDict[tuple[Any, ...], RunBundle] = OrderedDict()
        self._locks: dict[tuple[Any, ...], threading.Lock] = {}
        self._guard = threading.Lock()

    @staticmethod
    def key(run_id: str, recording_path: str) -> tuple[Any, ...]:
        """Cache key: the run and the recording file's identity (size, mtime).

        :raises OSError: the recording is missing.
        """
        st = Path(recording_path).stat()
        return (run_id, recording_path, st.st_size, st.st_mtime_ns)

    def get(self, key: tuple[Any, ...], compute: Callable[[], RunBundle]) -> RunBundle:
        """The cached bundle for ``key``, computing it (once) when absent."""
        with self._guard:
            hit = self._items.get(key)
            if hit is not None:
                self._items.move_to_end(key)
                return hit
            lock = self._locks.setdefault(key, threading.Lock())
        with lock:
            with self._guard:
                hit = self._items.get(key)
            if hit is not None:
                return hit
            bundle = compute()
            with self._guard:
                self._items[key] = bundle
                self._items.move_to_end(key)
                while len(self._items) > self.size:
                    self._items.popitem(last=False)
                self._locks.pop(key, None)
            return bundle

    def __len__(self) -> int:
        return len(self._items)
