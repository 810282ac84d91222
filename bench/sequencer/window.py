"""Collecting one window's samples as blocks stream past.

A window needs an exact number of samples, ``round(duration_s · sample_rate_hz)``; blocks do
not line up with that, so :class:`WindowCollector` takes what it needs from each block and
reports when it is full. It keeps running sums (means of every channel) and, for a noise
window, the samples themselves (for the Allan curve).
"""

from __future__ import annotations

import math

import numpy as np

from bench.records import WindowKind, WindowRecord


class WindowCollector:
    """Accumulates one window.

    :param index: window index.
    :param label: segment label.
    :param kind: what the table does meanwhile.
    :param n_needed: samples in the window (>= 1).
    :param pose_deg: commanded pose (deg).
    :param step_index: the step recording it.
    :param keep_samples: keep the accelerometer samples (noise window).
    """

    def __init__(
        self,
        index: int,
        label: str,
        kind: WindowKind,
        n_needed: int,
        pose_deg: tuple[float, ...],
        step_index: int,
        keep_samples: bool = False,
    ) -> None:
        self.index = index
        self.label = label
        self.kind = kind
        self.n_needed = max(1, n_needed)
        self.pose_deg = pose_deg
        self.step_index = step_index
        self.n = 0
        self.start_s = math.nan
        self.end_s = math.nan
        self._sum_accel = np.zeros(3)
        self._sum_table: np.ndarray | None = None
        self._sum_temp = 0.0
        self._n_temp = 0
        self._kept: list[np.ndarray] = []
        self._keep = keep_samples

    @property
    def full(self) -> bool:
        """The window has all its samples."""
        return self.n >= self.n_needed

    def add(self, t_s: np.ndarray, accel: np.ndarray, table_deg: np.ndarray, temp_c: np.ndarray) -> None:
        """Take as many leading samples of a block as the window still needs."""
        k = min(self.n_needed - self.n, int(t_s.size))
        if k <= 0:
            return
        if self.n == 0:
            self.start_s = float(t_s[0])
        self.end_s = float(t_s[k - 1])
        self._sum_accel += accel[:k].sum(axis=0)
        tab = table_deg[:k].sum(axis=0)
        self._sum_table = tab if self._sum_table is None else self._sum_table + tab
        finite = temp_c[:k][np.isfinite(temp_c[:k])]
        self._sum_temp += float(finite.sum())
        self._n_temp += int(finite.size)
        if self._keep:
            self._kept.append(np.array(accel[:k], dtype=float))
        self.n += k

    def samples(self) -> np.ndarray:
        """(n, 3) kept accelerometer samples (noise window)."""
        return np.vstack(self._kept) if self._kept else np.zeros((0, 3))

    def record(self) -> WindowRecord:
        """The completed window."""
        if self.n < 2:
            raise ValueError(f"window {self.label!r} has {self.n} samples; at least 2 are needed")
        mean_accel = self._sum_accel / self.n
        tab = self._sum_table
        mean_table = tuple(float(v) for v in tab / self.n) if tab is not None else ()
        temp = self._sum_temp / self._n_temp if self._n_temp else math.nan
        means = {"ax": float(mean_accel[0]), "ay": float(mean_accel[1]), "az": float(mean_accel[2])}
        if self._n_temp:
            means["temp"] = temp
        return WindowRecord(
            index=self.index,
            label=self.label,
            kind=self.kind,
            start_s=self.start_s,
            end_s=self.end_s,
            n_samples=self.n,
            pose_deg=tuple(self.pose_deg),
            mean_table_deg=mean_table,
            temp_c_mean=temp,
            step_index=self.step_index,
            means=means,
        )
