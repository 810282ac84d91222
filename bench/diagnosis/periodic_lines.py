"""Periodic lines in what the model leaves: a sinusoid on one or more channels (vibration,
mains, a pump, a fan), its frequency, amplitude and channel.

Where to look: on a static recording, each window's samples less the window's own mean and
slope (a line faster than a window averages out of the window means, so only the samples
carry it), the windows laid end to end; on a moving recording, the final model's residual
per sample. Lines are found by ``bench.estimation.spectral_lines.find_lines`` (Welch spectrum
against its local median, false alarm 10⁻³ over all bins and channels, a line narrower than
8 bins), its segments no longer than the power of two at or above twice the median run of
pieces that follow each other without a gap: laid end to end, windows join with a jump in the
line's phase, and a segment across many junctions widens a line beyond 8 bins (a 23.4 Hz line
in 3-11 s hand-placed windows was set aside as broadband under 4096-sample segments), while
a segment as short as one window halves a weak line's height over the median. The noise
density S near the line is read with segments no longer than one run, where the junctions'
skirt stays within the bins left out.

Each line found is then measured on the samples at their own time stamps (a line of a
pump keeps its phase across the gaps between windows): its frequency refined by the
periodogram maximum (``refine_frequency`` of the laid-out samples), and per channel the
coefficients (a, b) of sin and cos at f₀ by least squares beside each window's (or, moving,
each 10 s block's) mean and slope. With S the one-sided Welch density near f₀ (channel
units²/Hz, ``noise_level``: the median of the bins 5 to 16 away), white-like noise near f₀
gives var(a) = var(b) = S·f_s/N (N samples): the amplitude A = √(a² + b²) has
σ_A = √(S·f_s/N) (A ≫ σ_A), the frequency σ_f = σ_A·√(N / Σ(t − t̄)²) / (2π·A) (Cramér–Rao
bound for one sinusoid, Rife & Boorstyn 1974, at the samples' own times: √12·σ_A/(2π·A·T)
for one stretch of length T). The phase is that of sin(2π f₀ t + φ), t on the recording's clock.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.spectral_lines import capped_segment_length, find_lines, welch_segment_length

FloatArray = np.ndarray
CHANNELS = ("ax", "ay", "az")


@dataclass(frozen=True)
class Line:
    """One periodic line of a diagnosis.

    :param frequency_hz: f₀ and :param frequency_sigma_hz: its one sigma (Hz).
    :param amplitude: (3,) amplitude per channel (channel units, peak); :param amplitude_sigma: (3,).
    :param phase_rad: (3,) φ of A·sin(2π f₀ t + φ) per channel.
    :param channels: the channels the line was found on (0, 1, 2).
    :param ratio_to_median: the largest peak density over the local median.
    """

    frequency_hz: float
    frequency_sigma_hz: float
    amplitude: FloatArray
    amplitude_sigma: FloatArray
    phase_rad: FloatArray
    channels: tuple[int, ...]
    ratio_to_median: float

    def summary(self, channel_unit: str) -> str:
        """One sentence with the line's size."""
        parts = ", ".join(
            f"{CHANNELS[i]} {self.amplitude[i]:.3g} ± {self.amplitude_sigma[i]:.2g} {channel_unit}"
            for i in self.channels
        )
        return (
            f"a periodic line at {self.frequency_hz:.4g} ± {self.frequency_sigma_hz:.2g} Hz on {parts} (peak "
            f"amplitude; {self.ratio_to_median:.0f}× the local noise spectrum): a vibration, mains or a pump "
            "reaching the sensor; it averages out of window means but not out of samples"
        )


def _segments(pieces: list[tuple[FloatArray, FloatArray]]) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Laid-out samples (n, 3) less each piece's mean and slope, their times (n,), piece index (n,)."""
    ys, ts, idx = [], [], []
    for k, (t, y) in enumerate(pieces):
        tc = t - t.mean()
        X = np.column_stack([np.ones_like(tc), tc])
        coef = np.linalg.lstsq(X, y, rcond=None)[0]
        ys.append(y - X @ coef)
        ts.append(t)
        idx.append(np.full(t.size, k))
    return np.vstack(ys), np.concatenate(ts), np.concatenate(idx)


def _median_run(pieces: list[tuple[FloatArray, FloatArray]], fs: float) -> int:
    """Median length (samples) of the runs of pieces that follow each other without a gap
    (next first time within 1.5 sample periods of the last): the Welch segment of the line
    search stays within one run, where the line's phase is continuous."""
    runs = [pieces[0][0].size]
    for (t_prev, _), (t, _) in itertools.pairwise(pieces):
        if t[0] - t_prev[-1] <= 1.5 / fs:
            runs[-1] += t.size
        else:
            runs.append(t.size)
    return int(np.median(runs))


def _measure(
    y: FloatArray, t: FloatArray, piece: FloatArray, f0: float, fs: float, S: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(A, σ_A, φ) per channel of the sinusoid at f0, each piece's mean and slope beside it."""
    XtX = np.zeros((2, 2))
    Xty = np.zeros((2, 3))
    for k in range(int(piece.max()) + 1):  # each piece's mean and slope projected out (Frisch-Waugh)
        sel = piece == k
        tk = t[sel]
        N = np.column_stack([np.ones_like(tk), tk - tk.mean()])
        X = np.column_stack([np.sin(2 * np.pi * f0 * tk), np.cos(2 * np.pi * f0 * tk)])
        X -= N @ np.linalg.lstsq(N, X, rcond=None)[0]
        XtX += X.T @ X
        Xty += X.T @ y[sel]
    coef = np.linalg.solve(XtX, Xty)
    a, b = coef[0], coef[1]  # A sin(wt + φ) = A cos φ sin wt + A sin φ cos wt
    A = np.hypot(a, b)
    return A, np.sqrt(S * fs / y.shape[0]), np.arctan2(b, a)


def noise_level(p: FloatArray, k: int) -> FloatArray:
    """(3,) one-sided noise density near Welch bin k: the median of bins k ± 5 … k ± 16 (the
    line's own bins and skirt left out: laid-out windows join with phase jumps, which widen a
    line beyond the Hann main lobe)."""
    idx = np.r_[max(k - 16, 0) : max(k - 4, 0), k + 5 : min(k + 17, p.shape[0])]
    return np.asarray(np.median(p[idx], axis=0), dtype=float)


def refine_on_clock(
    y: FloatArray, t: FloatArray, f0_hz: float, half_width_hz: float, th: Thresholds = THRESHOLDS
) -> float:
    """f (Hz) in f0 ± half_width maximising |Σ y e^{−2πi f t}| at the samples' own times t (s).

    A grid of step 1/(10·(t_last − t_first)) (a tenth of the resolution of the whole span, gaps
    included, so that a line that keeps its phase across gaps is found at its own frequency;
    at most ``th.line_grid_max`` points), then a parabola through the best grid point and its neighbours.
    Where the grid limit made the step coarser than that, the search is repeated around the
    result with half-width two steps, until the step is the tenth of the resolution.
    """
    span = max(float(t[-1] - t[0]), 1e-9)
    step = max(0.1 / span, 2.0 * half_width_hz / th.line_grid_max)
    f_hz = _refine_grid(y, t, f0_hz, half_width_hz, step)
    while step > 0.1 / span * (1 + 1e-9):
        half_width_hz = 2.0 * step
        step = max(0.1 / span, 2.0 * half_width_hz / th.line_grid_max)
        f_hz = _refine_grid(y, t, f_hz, half_width_hz, step)
    return f_hz


def _refine_grid(y: FloatArray, t: FloatArray, f0_hz: float, half_width_hz: float, step: float) -> float:
    """One grid search of :func:`refine_on_clock` (grid f0 ± half_width, given step, parabola)."""
    grid = np.arange(f0_hz - half_width_hz, f0_hz + half_width_hz + step / 2, step)
    grid = grid[grid > 0]
    if grid.size < 3:
        return f0_hz
    tc = t - t[0]
    acc = np.zeros(grid.size, dtype=complex)
    for a in range(0, grid.size, 16):  # (16, 65536) complex blocks: 16 MB
        for b in range(0, tc.size, 1 << 16):
            ph = np.exp(-2j * np.pi * np.outer(grid[a : a + 16], tc[b : b + (1 << 16)]))
            acc[a : a + 16] += ph @ y[b : b + (1 << 16)]
    power = np.abs(acc) ** 2
    k = int(np.clip(np.argmax(power), 1, grid.size - 2))
    p0, p1, p2 = power[k - 1], power[k], power[k + 1]
    den = p0 - 2 * p1 + p2
    shift = 0.0 if den >= 0 else 0.5 * (p0 - p2) / den
    return float(grid[k] + np.clip(shift, -1.0, 1.0) * step)


def find_periodic_lines(
    pieces: list[tuple[FloatArray, FloatArray]], sample_rate_hz: float, th: Thresholds = THRESHOLDS
) -> tuple[Line, ...]:
    """Lines in samples (module docstring).

    :param pieces: (t (n_k,) s, y (n_k, 3) channel units) per window or stretch of residual.
    :returns: one :class:`Line` per frequency found (on one or several channels), by frequency.
    """
    pieces = [(t, y) for t, y in pieces if t.size >= 16]
    if not pieces:
        return ()
    y, t, piece = _segments(pieces)
    if y.shape[0] < 64:
        return ()
    fs = float(sample_rate_hz)
    run = _median_run(pieces, fs)
    found = find_lines(y, fs, 1 << math.ceil(math.log2(2 * run)))
    if not found:
        return ()
    nper = capped_segment_length(welch_segment_length(y.shape[0]), run)  # S: the skirt kept out
    from scipy import signal  # lines were found: scipy.signal is loaded already

    _, p = signal.welch(y, fs=fs, nperseg=nper, axis=0, detrend="linear")
    bin_hz = fs / nper
    groups: list[list[int]] = []
    for i, ln in enumerate(sorted(found, key=lambda x: x.frequency_hz)):
        prev = sorted(found, key=lambda x: x.frequency_hz)
        if groups and abs(ln.frequency_hz - prev[groups[-1][0]].frequency_hz) <= 2 * bin_hz:
            groups[-1].append(i)
        else:
            groups.append([i])
    ordered = sorted(found, key=lambda x: x.frequency_hz)
    spread = float(np.sum((t - t.mean()) ** 2))
    out = []
    for g in groups:
        best = max((ordered[i] for i in g), key=lambda x: x.ratio_to_median)
        f0 = refine_on_clock(y[:, best.channel], t, best.frequency_hz, bin_hz, th)
        S = noise_level(p, round(f0 / bin_hz))
        A, sA, ph = _measure(y, t, piece, f0, fs, S)
        c0 = best.channel
        sf = sA[c0] * math.sqrt(t.size / max(spread, 1e-300)) / (2 * math.pi * max(A[c0], 1e-300))
        out.append(
            Line(
                frequency_hz=float(f0),
                frequency_sigma_hz=float(sf),
                amplitude=A,
                amplitude_sigma=sA,
                phase_rad=ph,
                channels=tuple(sorted({ordered[i].channel for i in g})),
                ratio_to_median=float(best.ratio_to_median),
            )
        )
    return tuple(out)


def without_lines(
    pieces: list[tuple[FloatArray, FloatArray]], lines: tuple[Line, ...]
) -> tuple[FloatArray, ...]:
    """Each piece's samples (n_k, 3) less every line's fitted sinusoid A_i sin(2π f₀ t + φ_i)."""
    out = []
    for t, y in pieces:
        yc = np.array(y, dtype=float, copy=True)
        for ln in lines:
            yc -= ln.amplitude * np.sin(2 * np.pi * ln.frequency_hz * t[:, None] + ln.phase_rad)
        out.append(yc)
    return tuple(out)


def residual_stretches(
    t: FloatArray, r: FloatArray, valid: FloatArray, block_s: float
) -> list[tuple[FloatArray, FloatArray]]:
    """A moving residual (n, 3) cut into blocks of ``block_s`` of consecutive valid samples."""
    out = []
    ok = np.asarray(valid, dtype=bool)
    blk = np.floor((t - t[0]) / block_s).astype(np.int64)
    for b in np.unique(blk[ok]):
        sel = ok & (blk == b)
        out.append((t[sel], r[sel]))
    return out
