"""Is a recording physically plausible? Faults a real table and DAQ have, found in the data.

Every recording, static or moving, passes these before and after its fit
(``bench.calibration.recording.calibrate_recording``): a fault the fit would absorb silently
(its result moved, its residual hardly grown) becomes a sentence in ``warnings`` (the
``calibrate --json`` object, the service's upload answer, stderr), and data that cannot be used
as they stand are refused (:class:`ValueError`, one line: exit 2).

Before the fit (:func:`recording_findings`, on the samples alone):

- **channel scale** (refusal): a channel whose spread (0.5–99.5 % range) is more than
  :data:`MAX_RANGE_RATIO` times larger or smaller than the median channel's. A triad's
  channels see the same specific force through gains of one order; the largest honest
  ratio is a channel that sees only its noise (range ≈ 6σ, σ ≥ 1e-5 g) against one that sees
  ±g: 2g / 6σ ≈ 3e4 at the quietest sensors, ≈ 3e2 at ADXL-like ones. A channel multiplied
  by 1e6 (a wrong unit or gain) is far beyond, and its fit would fail on a false "K is
  singular" or succeed with a K that means nothing.
- **spikes** (warning): samples that depart from the running median of
  :data:`SPIKE_MEDIAN_SAMPLES` samples by more than :data:`SPIKE_SIGMA` robust standard
  deviations (1.4826 × the median absolute departure in the sample's block of
  :data:`NOISE_BLOCK_SAMPLES` and its neighbours, over the samples that depart at all: a
  clipped, flat stretch would shrink it), in runs of at most :data:`MAX_SPIKE_SAMPLES`
  samples. A running median keeps steps and slow motion (a table that starts turning) and
  removes runs shorter than half its width; for Gaussian noise a
  departure of 12 σ has probability 4e-33 per sample, so a clean recording of any length
  gives none.
- **clipping** (warning): a channel whose largest (or smallest) value is held by at least
  :data:`MIN_CLIP_SAMPLES` samples and more than :data:`CLIP_EXCESS` times as many as any
  other value: the tail of a distribution thins out towards its extreme, a rail collects
  everything beyond it (an ADC or a sensor at its limit). A channel quantised more coarsely
  than its noise (more than :data:`MAX_TIE_SHARE` of consecutive samples equal, counted where
  neither sample is at the channel's extremes: a rail holding most samples makes ties there
  alone) is not judged.
- **encoder resolution** (warning): a table column whose angles, while the table moves,
  scatter about a smooth motion (a quadratic Savitzky-Golay fit over
  :data:`ANGLE_SMOOTH_SAMPLES` samples) by more than :data:`MAX_ANGLE_SCATTER_DEG` (robust
  sigma): a grid of q scatters by q/√12 (0.14° for encoders rounded to 0.5°), a continuous
  encoder on a smooth trajectory by nothing, kinks between motions touch a few samples
  only. That error enters every sample's attitude on a moving table; the fit's uncertainty
  does not contain it. A held pose shows no scatter, so a static recording is not judged.

After the fit (:func:`fit_findings`, on the fitted model):

- **frame**: the fitted axes a mirror image of the nominal frame (det K < 0: an axis sign or
  ``mount_rotation`` wrong), or turned more than :data:`MAX_MISALIGNMENT_DEG` (polar
  decomposition K = R·S, angle of R): a wrong mount or encoder zero gives a perfect fit with
  every K element moved, which no residual shows;
- **gains**: the channels' fitted gains (row norms of K, channel unit per m/s²) differ by
  more than :data:`MAX_GAIN_RATIO` (one channel's unit or gain wrong);
- **encoder lag**: a moving fit whose ``time_skew`` term (chosen by its evidence) puts the
  encoders and the DAQ more than one sample period apart: the model corrects a skew to first
  order only, and a lag of whole samples is a fault of the recording's time stamps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.ndimage import median_filter

from bench.recording.model import Recording

FloatArray = npt.NDArray[np.float64]

CHANNELS = ("ax", "ay", "az")
MAX_RANGE_RATIO = 1e4
"""Largest ratio of a channel's 0.5–99.5 % range to the median channel's (either way)."""
SPIKE_MEDIAN_SAMPLES = 9
"""Width of the running median spikes are measured from (samples): removes runs of up to 4."""
SPIKE_SIGMA = 12.0
"""Departure from the running median, in robust standard deviations, that makes a spike."""
NOISE_BLOCK_SAMPLES = 32
"""Block over which the noise a spike is measured against is estimated (samples)."""
MAX_SPIKE_SAMPLES = 4
"""Longest run of departing samples counted as one spike (a longer one is not a spike)."""
MIN_CLIP_SAMPLES = 5
CLIP_EXCESS = 3.0
"""A rail holds more than this many times the samples of any other value."""
MAX_TIE_SHARE = 0.5
"""Share of repeated consecutive values beyond which a channel is too coarsely quantised to judge."""
ANGLE_SMOOTH_SAMPLES = 11
"""Savitzky-Golay window (samples, quadratic) of the smooth motion encoder angles are measured from."""
MAX_ANGLE_SCATTER_DEG = 0.003
"""Largest robust scatter of a moving encoder's angles about a smooth motion accepted silently (deg):
the uniform error q/√12 of a 0.01° grid."""
MIN_MOVING_SAMPLES = 100
"""Samples in motion a column needs before its scatter is judged (a held pose shows none)."""
MAX_MISALIGNMENT_DEG = 5.0
"""Largest rotation between the fitted sensor axes and the nominal frame believed without a warning."""
MAX_GAIN_RATIO = 3.0
"""Largest ratio between the fitted gains of two channels of one triad believed without a warning."""


@dataclass(frozen=True)
class Finding:
    """One implausibility: ``kind`` (``spikes``, ``clipping``, ``encoder_resolution``,
    ``channel_scale``, ``frame``, ``gains``, ``encoder_lag``) and the sentence a reader gets."""

    kind: str
    text: str


def recording_findings(rec: Recording) -> tuple[Finding, ...]:
    """Warnings about the samples of ``rec`` (module docstring).

    :raises ValueError: a channel whose scale is off by more than :data:`MAX_RANGE_RATIO`.
    """
    y = np.asarray(rec.accel_raw, dtype=float)
    if y.ndim != 2 or y.shape[0] < SPIKE_MEDIAN_SAMPLES or not np.all(np.isfinite(y)):
        return ()  # the fit refuses these with its own message
    check_channel_scale(y, rec.sidecar.channel_unit)
    found = [
        f for c in range(3) for f in (_spikes(rec.t_s, y[:, c], CHANNELS[c]), _clipping(y[:, c], CHANNELS[c]))
    ]
    table = rec.table_rad_unwrapped()
    if table is not None and table.shape[0] >= ANGLE_SMOOTH_SAMPLES and np.all(np.isfinite(table)):
        for i in range(table.shape[1]):
            found.append(_angle_scatter(np.degrees(table[:, i]), f"table_{i + 1}"))
    return tuple(f for f in found if f is not None)


def check_channel_scale(y: FloatArray, unit: str) -> None:
    """Refuse a channel whose 0.5–99.5 % range is off the median channel's by more than
    :data:`MAX_RANGE_RATIO` (either way), naming it and the ranges.

    :param y: (n, 3) raw samples; :param unit: their unit (for the message).
    :raises ValueError: one line.
    """
    lo, hi = np.percentile(y, [0.5, 99.5], axis=0)
    spread = hi - lo
    mid = float(np.median(spread))
    if mid <= 0:
        return
    ratio = spread / mid
    c = int(np.argmax(np.abs(np.log10(np.maximum(ratio, 1e-300)))))
    if ratio[c] > MAX_RANGE_RATIO or ratio[c] < 1 / MAX_RANGE_RATIO:
        ranges = ", ".join(f"{n} {s:.3g}" for n, s in zip(CHANNELS, spread, strict=True))
        raise ValueError(
            f"channel {CHANNELS[c]} spans {ratio[c]:.3g} times the range of the median channel "
            f"(0.5-99.5 % ranges in {unit}: {ranges}): a wrong gain or unit on {CHANNELS[c]}; "
            f"expected the channels of one triad within {MAX_RANGE_RATIO:g} times of each other"
        )


def _runs(mask: npt.NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(start, stop) of each run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def _local_sigma(dep: FloatArray, floor: float) -> FloatArray:
    """(n,) robust standard deviation of ``dep`` about each sample: 1.4826 × the median |dep| of
    the nonzero departures in its block of :data:`NOISE_BLOCK_SAMPLES`, the largest of the block
    and its two neighbours (noise that changes along the recording, e.g. handling between
    poses, is judged by its own level), never below ``floor``."""
    n = dep.shape[0]
    n_blocks = -(-n // NOISE_BLOCK_SAMPLES)
    # all blocks at once: each row sorted with its zero departures (the window medians, a flat
    # clipped stretch) and the last block's padding moved to the end as +inf; the median of a
    # row's k nonzero values is its middle one, or the mean of the two middle ones (np.median's)
    blocks = np.full(n_blocks * NOISE_BLOCK_SAMPLES, np.inf)
    blocks[:n] = np.where(dep != 0, np.abs(dep), np.inf)
    rows = np.sort(blocks.reshape(n_blocks, NOISE_BLOCK_SAMPLES), axis=1)
    k = np.count_nonzero(np.isfinite(rows), axis=1)
    lo = rows[np.arange(n_blocks), np.maximum(k - 1, 0) // 2]
    hi = rows[np.arange(n_blocks), np.minimum(k // 2, NOISE_BLOCK_SAMPLES - 1)]
    med = np.where(k % 2 == 1, lo, (lo + hi) / 2.0)
    sig = np.where(k > 0, 1.4826 * med, 0.0)
    padded = np.concatenate([sig[:1], sig, sig[-1:]])
    local = np.maximum(np.maximum(padded[:-2], padded[1:-1]), padded[2:])
    return np.repeat(np.maximum(local, floor), NOISE_BLOCK_SAMPLES)[:n]


def _spikes(t_s: FloatArray, v: FloatArray, name: str) -> Finding | None:
    dep = v - median_filter(v, size=SPIKE_MEDIAN_SAMPLES, mode="nearest")
    steps = np.abs(np.diff(v))
    quantum = float(steps[steps > 0].min()) if np.any(steps > 0) else 0.0
    sigma = _local_sigma(dep, quantum)
    far = np.abs(dep) > SPIKE_SIGMA * sigma
    far &= sigma > 0
    spikes = [(a, b) for a, b in _runs(far) if b - a <= MAX_SPIKE_SAMPLES]
    if not spikes:
        return None
    sizes = [float(np.max(np.abs(dep[a:b]) / sigma[a:b])) for a, b in spikes]
    n_samples = sum(b - a for a, b in spikes)
    return Finding(
        "spikes",
        f"channel {name}: {len(spikes)} spike(s) ({n_samples} samples, runs of at most {MAX_SPIKE_SAMPLES}) "
        f"departing from their neighbours by {min(sizes):.3g}-{max(sizes):.3g} times the channel's noise "
        f"(first at t = {float(t_s[spikes[0][0]]):.6g} s); the fit uses them as they are",
    )


def _clipping(v: FloatArray, name: str) -> Finding | None:
    off = (v != v.min()) & (v != v.max())
    inner = off[:-1] & off[1:]  # consecutive pairs off the extremes, where a rail cannot make ties
    ties = float(np.mean(np.diff(v)[inner] == 0)) if inner.any() else 1.0
    if ties > MAX_TIE_SHARE:
        return None  # quantised more coarsely than its noise: no level can be told from a rail
    values, counts = np.unique(v, return_counts=True)
    if values.size < 2:
        return None
    for i, side in ((-1, "largest"), (0, "smallest")):
        others = int(np.max(np.delete(counts, i if i >= 0 else counts.size - 1)))
        if counts[i] >= MIN_CLIP_SAMPLES and counts[i] > CLIP_EXCESS * others:
            return Finding(
                "clipping",
                f"channel {name} holds its {side} value {values[i]:.6g} in {int(counts[i])} samples "
                f"({counts[i] / v.size:.1%}; no other value in more than {others}): clipped at a rail; "
                "the fit takes the clipped values as measured",
            )
    return None


def _quadratic_fit(angle_deg: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(value, slope per sample) of the least-squares quadratic over :data:`ANGLE_SMOOTH_SAMPLES`
    samples centred on each interior sample (Savitzky-Golay: rows 0 and 1 of the pseudo-inverse
    of the window's Vandermonde matrix [1, x, x²], x = −h..h), for samples h..n−h−1."""
    h = ANGLE_SMOOTH_SAMPLES // 2
    x = np.arange(-h, h + 1, dtype=float)
    coef = np.linalg.pinv(np.column_stack([np.ones_like(x), x, x * x]))
    value = np.convolve(angle_deg, coef[0][::-1], mode="valid")
    slope = np.convolve(angle_deg, coef[1][::-1], mode="valid")
    return value, slope


def _angle_scatter(angle_deg: FloatArray, name: str) -> Finding | None:
    smooth, slope = _quadratic_fit(angle_deg)
    h = ANGLE_SMOOTH_SAMPLES // 2
    moving = np.abs(slope) > 1e-9
    if int(moving.sum()) < MIN_MOVING_SAMPLES:
        return None
    sigma = 1.4826 * float(np.median(np.abs((angle_deg[h:-h] - smooth)[moving])))
    if sigma <= MAX_ANGLE_SCATTER_DEG:
        return None
    return Finding(
        "encoder_resolution",
        f"{name}: while the table moves its angles scatter by {sigma:.3g}° (robust sigma) about a smooth "
        f"motion, more than {MAX_ANGLE_SCATTER_DEG:g}° (an encoder resolution of about "
        f"{sigma * math.sqrt(12):.2g}° or a noisy encoder): each sample's attitude carries that error, "
        "which the fit's uncertainty does not contain",
    )


def misalignment_deg(K: FloatArray) -> tuple[float, bool]:
    """Rotation angle (deg) of the orthogonal factor of K (polar decomposition K = R·S, R = U·Vᵀ from
    the SVD K = U·Σ·Vᵀ; angle = arccos((tr R − 1)/2)), and whether R is a reflection (det < 0)."""
    U, _, Vt = np.linalg.svd(np.asarray(K, dtype=float))
    R = U @ Vt
    if np.linalg.det(R) < 0:
        return 180.0, True
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))), False


def fit_findings(
    K: FloatArray,
    *,
    frame_known: bool,
    channel_unit: str,
    time_skew_s: float | None = None,
    sample_rate_hz: float | None = None,
) -> tuple[Finding, ...]:
    """Warnings about a fitted model (module docstring).

    :param K: (3, 3) fitted scale/misalignment (channel unit per m/s²).
    :param frame_known: the fit knows the sensor's orientation (static or moving table); an
        orientation-free fit gives K only up to a rotation, so its frame is not judged.
    :param time_skew_s: the fitted delay between encoders and DAQ (s), ``None`` when not fitted.
    :param sample_rate_hz: the recording's rate, for the lag in samples.
    """
    K = np.asarray(K, dtype=float)
    found: list[Finding] = []
    if not np.all(np.isfinite(K)):
        return ()
    if frame_known:
        angle, reflected = misalignment_deg(K)
        if reflected:
            found.append(
                Finding(
                    "frame",
                    "the fitted sensor axes are a mirror image of the nominal frame (det K < 0): an axis "
                    "sign or the sidecar's mount_rotation is wrong",
                )
            )
        elif angle > MAX_MISALIGNMENT_DEG:
            found.append(
                Finding(
                    "frame",
                    f"the fitted sensor axes are turned {angle:.1f}° from the nominal frame (more than "
                    f"{MAX_MISALIGNMENT_DEG:g}°): check the sidecar's mount_rotation and the encoder zeros",
                )
            )
    gains = np.linalg.norm(K, axis=1)
    if np.all(gains > 0) and gains.max() / gains.min() > MAX_GAIN_RATIO:
        listed = ", ".join(f"{n} {g:.3g}" for n, g in zip(CHANNELS, gains, strict=True))
        found.append(
            Finding(
                "gains",
                f"the channels' fitted gains differ {gains.max() / gains.min():.3g} times ({listed} "
                f"{channel_unit} per m/s2; expected within {MAX_GAIN_RATIO:g} times in one triad): a "
                "channel's gain or unit is wrong",
            )
        )
    if time_skew_s is not None and sample_rate_hz and abs(time_skew_s) * sample_rate_hz > 1.0:
        found.append(
            Finding(
                "encoder_lag",
                f"the encoders and the DAQ are {time_skew_s * 1e3:.4g} ms apart "
                f"({time_skew_s * sample_rate_hz:.3g} samples; time_skew fitted): more than one sample "
                "period, which the model corrects to first order only; check the recording's time stamps",
            )
        )
    return tuple(found)
