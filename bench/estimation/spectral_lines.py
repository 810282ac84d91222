"""Periodic lines in a static record: find them in the spectrum, take them out of the noise.

A line is a sinusoid y(t) = A·sin(2π f₀ t + φ) on top of broadband noise (a pump, a fan, a
mains-locked vibration, a DAQ clock beat). Its Allan variance A²·sin⁴(πf₀τ)/(πf₀τ)² (IEEE
Std 952-1997, Annex C, "sinusoidal noise") falls as 1/τ² beyond τ ≈ 1/(2f₀): a 0.5 Hz line
under τ ≈ 1 s looks like white noise, a 23.4 Hz line at 100 Hz like quantisation noise.

Finding (:func:`find_lines`): the one-sided Welch power spectral density P(f) of each channel
(Hann window, 50 % overlap, segments of :func:`welch_segment_length`; SciPy ``welch``), the
local median M(f) over ±max(8, f/(8·Δf)) bins (an eighth of the frequency: follows 1/f and
1/f² noise), and the ratio P/M. For noise alone P/M is about χ²_ν/ν with ν ≈ 2·(number of
segments) (Welch 1967), so a bin is *above* when P/M exceeds the larger of
:data:`MIN_LINE_RATIO` and the χ²_ν quantile at false-alarm 10⁻³ divided over all bins and
channels. Adjacent bins above are one peak; a peak no wider than :data:`MAX_LINE_BINS` bins
is a line (the Hann main lobe is 4 bins wide), a wider one is broadband (a resonance) and is
left in the noise. Frequency: the power-weighted centroid of the peak's bins. Amplitude: the
peak's power above the median, ∫(P − M) df = A²/2 (Parseval; density scaling), over the
peak's bins and two on each side. Bins below 8 Δf have too few neighbours; the frequencies
below that floor are searched by a second pass with the longest segments that still give
three (:func:`low_segment_length`; its own ν, the same rule), so a 0.5 Hz line in a 50 s
record is found. The false-alarm probability is divided over the bins of both passes.

Removing (:func:`remove_lines`): per line, sin and cos at f₀ fitted by least squares in
blocks of :func:`line_block_s` and subtracted. A block holds ≥ 200 periods so a slow drift of
the line's amplitude or phase is followed, while each block takes out only two degrees of
freedom of the noise (a fraction 1/(f₀·block) of the noise near f₀, ≤ 0.5 %).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import stats

FloatArray = npt.NDArray[np.float64]

MIN_LINE_RATIO = 20.0
"""A line stands at least this far above the local median spectrum."""

MAX_LINE_BINS = 8
"""A peak wider than this many Welch bins is broadband, not a line."""

FALSE_ALARM = 1e-3
"""Probability that noise alone yields a line anywhere in one analysis."""

MIN_PERIODS_PER_BLOCK = 200.0
"""A removal block holds at least this many periods of the line."""


@dataclass(frozen=True)
class SpectralLine:
    """One periodic line.

    :param channel: column index of the data it was found in.
    :param frequency_hz: f₀ (Hz), power-weighted centroid of the peak's bins.
    :param amplitude: A, the sinusoid's amplitude in the channel's unit (peak, not RMS).
    :param ratio_to_median: peak density over the local median density.
    :param width_hz: width of the peak's bins above threshold (Hz).
    """

    channel: int
    frequency_hz: float
    amplitude: float
    ratio_to_median: float
    width_hz: float


def welch_segment_length(n_samples: int) -> int:
    """Welch segment length: a power of two giving ≥ 16 segments (50 % overlap), 256 … 65536."""
    target = max(n_samples // 8, 1)
    return int(min(max(2 ** math.floor(math.log2(max(target, 2))), 256), 1 << 16, n_samples))


def local_median(p: FloatArray, min_half_width: int = 8) -> FloatArray:
    """(k,) median of p over ±max(min_half_width, i/8) bins around each bin i.

    Evaluated exactly at every bin up to 8·min_half_width and at 400 log-spaced bins beyond,
    interpolated in log power between them (the median spectrum of 1/f-type noise is smooth
    on that scale).
    """
    k = p.size

    def med(i: int) -> float:
        h = max(min_half_width, i // 8)
        return float(np.median(p[max(0, i - h) : i + h + 1]))

    dense = min(k, 8 * min_half_width)
    centers = np.unique(
        np.concatenate([np.arange(dense), np.geomspace(max(dense, 1), k - 1, 400).astype(int)])
    )
    centers = centers[centers < k]
    values = np.array([med(int(i)) for i in centers])
    logv = np.log(np.maximum(values, np.finfo(float).tiny))
    return np.asarray(np.exp(np.interp(np.arange(k), centers, logv)), dtype=float)


def _peaks(above: npt.NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Runs [start, stop) of consecutive True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], above.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def find_lines(
    y: npt.ArrayLike, sample_rate_hz: float, max_segment: int | None = None
) -> tuple[SpectralLine, ...]:
    """Narrow lines far above the local median spectrum, per channel (see module doc).

    :param y: (n,) or (n, c) evenly spaced samples, finite.
    :param sample_rate_hz: sampling rate (Hz), > 0.
    :param max_segment: longest Welch segment (samples), for samples laid end to end from
        stretches of about that length: a segment across a junction sees the line's phase
        jump, which widens its peak beyond :data:`MAX_LINE_BINS`. ``None``: no limit.
    :returns: lines sorted by channel, then frequency.
    """
    data = np.asarray(y, dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2 or data.shape[0] < 64:
        raise ValueError(f"find_lines needs (n, c) data with n ≥ 64, got shape {np.shape(y)}")
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"sample_rate_hz must be finite and > 0, got {sample_rate_hz}")
    n, c = data.shape
    nper = capped_segment_length(welch_segment_length(n), max_segment)
    passes: list[tuple[int, int, int | None]] = [(nper, 8, None)]
    nper_low = capped_segment_length(low_segment_length(n), max_segment)
    if nper_low > nper:  # the frequencies below the first pass's floor, 8·fs/nper
        passes.append((nper_low, 8, 8 * nper_low // nper))
    from scipy import signal  # where a line search runs: the static paths stay without it

    spectra = []
    for seg, lo, hi in passes:
        f, p = signal.welch(data, fs=sample_rate_hz, nperseg=seg, axis=0, detrend="linear")
        spectra.append((f, p, seg, lo, f.size if hi is None else min(hi, f.size)))
    n_tests = max(1, c * sum(max(hi - lo, 0) for _, _, _, lo, hi in spectra))
    lines: list[SpectralLine] = []
    for f, p, seg, lo, hi in spectra:
        lines.extend(_search(f, p, max(1, 2 * (n // seg) - 1), lo, hi, n_tests))
    return tuple(sorted(lines, key=lambda ln: (ln.channel, ln.frequency_hz)))


def capped_segment_length(nper: int, max_segment: int | None) -> int:
    """nper, or the largest power of two ≤ ``max_segment`` (at least 64) when that is shorter."""
    if max_segment is None:
        return nper
    return min(nper, int(2 ** math.floor(math.log2(max(max_segment, 64)))))


def low_segment_length(n_samples: int) -> int:
    """Segment length of the low-frequency pass: the longest power of two giving ≥ 3 Welch
    segments (50 % overlap), so that lines below the first pass's floor are searched too."""
    return int(2 ** math.floor(math.log2(max(n_samples // 2, 2))))


def _search(f: FloatArray, p: FloatArray, n_seg: int, lo: int, hi: int, n_tests: int) -> list[SpectralLine]:
    """Lines among bins [lo, hi) of one Welch pass (frequencies f (k,), densities p (k, c))."""
    df = float(f[1] - f[0])
    nu = 2.0 * n_seg * 0.9  # Hann, 50 % overlap: segments are correlated, ~10 % fewer dof
    threshold = max(MIN_LINE_RATIO, float(stats.chi2.isf(FALSE_ALARM / n_tests, nu)) / nu)
    lines: list[SpectralLine] = []
    for ch in range(p.shape[1]):
        pc = p[:, ch]
        med = np.maximum(local_median(pc), np.finfo(float).tiny)
        ratio = pc / med
        above = ratio > threshold
        above[:lo] = False
        above[hi:] = False
        for start, stop in _peaks(above):
            if stop - start > MAX_LINE_BINS:
                continue
            sel = slice(start, stop)
            f0 = float(np.sum(f[sel] * pc[sel]) / np.sum(pc[sel]))
            wide = slice(max(start - 2, 0), min(stop + 2, f.size))
            power = float(np.sum(np.maximum(pc[wide] - med[wide], 0.0)) * df)
            lines.append(
                SpectralLine(
                    channel=ch,
                    frequency_hz=f0,
                    amplitude=math.sqrt(2.0 * power),
                    ratio_to_median=float(ratio[sel].max()),
                    width_hz=(stop - start) * df,
                )
            )
    return lines


def refine_frequency(y: FloatArray, sample_rate_hz: float, f0_hz: float, half_width_hz: float) -> float:
    """f (Hz) in f0 ± half_width maximising the whole record's periodogram |Σ y e^{−2πi f t}|.

    The record's FFT bin of largest magnitude in that range, then a golden-section search
    within ± one FFT bin of it; the Welch centroid is only good to a fraction of a Welch bin,
    the whole record to about 1/(record length · SNR).
    """
    yc = y - y.mean()
    n = yc.size
    spec = np.abs(np.fft.rfft(yc))
    fb = np.fft.rfftfreq(n, 1.0 / sample_rate_hz)
    in_range = np.flatnonzero(np.abs(fb - f0_hz) <= half_width_hz)
    if in_range.size == 0:
        return f0_hz
    k = int(in_range[np.argmax(spec[in_range])])
    t = np.arange(n) / sample_rate_hz

    def power(fr: float) -> float:
        return float(abs(np.dot(yc, np.exp(-2j * np.pi * fr * t))))

    step = sample_rate_hz / n
    a, b = fb[k] - step, fb[k] + step
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = b - golden * (b - a), a + golden * (b - a)
    p1, p2 = power(x1), power(x2)
    for _ in range(24):
        if p1 > p2:
            b, x2, p2 = x2, x1, p1
            x1 = b - golden * (b - a)
            p1 = power(x1)
        else:
            a, x1, p1 = x1, x2, p2
            x2 = a + golden * (b - a)
            p2 = power(x2)
    return float(0.5 * (a + b))


def line_block_s(frequency_hz: float, duration_s: float) -> float:
    """Length of a removal block (s): ≥ 200 periods, at most the record."""
    return min(duration_s, MIN_PERIODS_PER_BLOCK / frequency_hz)


def remove_lines(
    y: npt.ArrayLike, sample_rate_hz: float, lines: tuple[SpectralLine, ...]
) -> tuple[FloatArray, tuple[SpectralLine, ...]]:
    """y with each line's sinusoid subtracted from its channel (see module doc).

    :returns: (n, c) cleaned data, and the lines with their frequency refined on the whole record.
    """
    data = np.array(y, dtype=float, copy=True)
    squeeze = data.ndim == 1
    if squeeze:
        data = data[:, None]
    n = data.shape[0]
    duration = n / sample_rate_hz
    refined: list[SpectralLine] = []
    for line in lines:
        ch = data[:, line.channel]
        bin_hz = sample_rate_hz / welch_segment_length(n)
        f0 = refine_frequency(ch, sample_rate_hz, line.frequency_hz, bin_hz)
        n_blocks = max(1, int(n // max(line_block_s(f0, duration) * sample_rate_hz, 1.0)))
        edges = np.linspace(0, n, n_blocks + 1).astype(int)
        for a, b in itertools.pairwise(edges.tolist()):
            t = np.arange(a, b) / sample_rate_hz
            X = np.column_stack([np.sin(2 * np.pi * f0 * t), np.cos(2 * np.pi * f0 * t), np.ones(b - a)])
            coef = np.linalg.lstsq(X, ch[a:b], rcond=None)[0]
            ch[a:b] -= X[:, :2] @ coef[:2]
        refined.append(SpectralLine(line.channel, f0, line.amplitude, line.ratio_to_median, line.width_hz))
    return (data[:, 0] if squeeze else data), tuple(refined)
