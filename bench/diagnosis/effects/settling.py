"""``settling``: the table still rings after a move when the window starts.

A ring of the table structure after a stop, δθ(s) = A·e^(−s/τ)·sin(2π f_r s) about the axes
that moved, adds to the first seconds of each window a narrow-band oscillation at f_r whose
power decays as e^(−2s/τ). Test (a narrow-band excess-power detector, frequency unknown):

- every window-channel is cut into consecutive segments of ``Thresholds.settling_segment_s``; each segment is
  detrended (mean and slope: bias wander) and its periodogram P(f_j) taken at the Fourier
  frequencies f_j = j / segment (j ≥ 2, below 0.9 × Nyquist);
- the reference spectrum of channel c, P_ref(c, f_j), is the mean periodogram of the
  segments in the second half of every window at the neighbouring frequencies f_{j±2},
  f_{j±3} (the same estimator, so the ratio is unbiased for a smooth noise spectrum; the
  ring's own bin and its nearest neighbours are left out, since a long ring is still
  there in the second half); it rests on d_ref(j) = 2 × (late segments) × (neighbours
  used) degrees of freedom per channel. Removing the mean and slope takes a share of the
  power of the lowest bins (``detrended_response``: h_j = 1 − 0.30/j² for a 2 s segment,
  0.92 at 1 Hz, 0.99 at 2.5 Hz), so each neighbour is divided by its h_k and the mean
  multiplied by h_j: without that the reference was biased at the lowest frequencies
  (mean early/reference ratio over 1000 clean simulated recordings 0.952 at 1 Hz and
  1.025 at 2.5 Hz, 16 and 7.5 standard errors from 1; the ratio that h predicts, 0.94 and
  1.02);
- the early segments are the first ``Thresholds.settling_early_segments`` of each window (at most half of
  them, so they never overlap the reference's second half); for each f_j,
  T_j = Σ over windows, channels and early segments of 2 P(f_j) / P_ref(c, f_j);
- null distribution: a periodogram ordinate of stationary noise is PSD·χ²₂/2, so
  T_j / (2n) (n ordinates, n/3 per channel) is the mean over the three channels of
  F(2n/3, d_ref) ratios, whose denominators (the references) are random. It is judged
  as F(2n, 3 d_ref): the three independent references act as one reference with three
  times the degrees of freedom (Monte Carlo with the static-12 sizes, 2n = 216,
  d_ref = 768: the tail at 1e-5 is 1.1–1.2 times the F's). Treating the reference as
  exact (T_j ~ χ²_2n) understated the tail threefold and gave 1.3 % false alarms at
  a nominal 0.1 % on clean recordings (benchmarks/study_settling_null.py);
- the smallest p over the f_j, times their number (Bonferroni), is the test's p value.

A ring is narrow-band; one altered sample (a spike, a byte flipped) is broadband: it raises
every ordinate of its segment alike, and alone it would pass the test at every frequency.
So an early segment-channel whose median ratio 2P/P_ref over the tested bins is beyond
what stationary noise gives (each ratio ≈ χ²₂, so the median of nb of them exceeds x with
probability ``binom.sf(ceil(nb/2) − 1, nb, e^(−x/2))``; below ``Thresholds.settling_broadband_alpha``)
is left out of T_j and of n: a ring, which lifts one bin and its neighbours, leaves the median
where it was.

Duration (the contract's ``duration_s``): at the detected frequency the mean ratio
R_k = mean_{w,c} P_k / P_ref of segment k (centre s_k after the window start) follows
R_k = 1 + B e^(−2 s_k / τ); weighted least squares over the segments of the first half
gives τ (its variance scaled by the fit's χ²/dof when that exceeds 1), and the bench's
ring convention (docs/physics-model.md: amplitude 0.05° decaying to 1e-4°) gives
duration_s = τ · ln(0.05 / 1e-4), its sigma from the fit's covariance.
Without the window samples (evidence reduced to means) nothing can be tested.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import curve_fit
from scipy.stats import binom
from scipy.stats import f as f_dist

from bench.diagnosis.effects.base import Candidate, EffectKind, FloatArray, ParamSpec
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


def broadband(ratio: FloatArray, alpha: float) -> npt.NDArray[np.bool_]:
    """(k, 3) early segment-channels whose ratios 2P/P_ref (``ratio``: (k, nb, 3), each ≈ χ²₂ under
    no ring) are lifted across the band: median over the nb bins beyond its level ``alpha``
    (``Thresholds.settling_broadband_alpha``)."""
    nb = ratio.shape[1]
    med = np.median(ratio, axis=1)
    p = binom.sf(math.ceil(nb / 2) - 1, nb, np.exp(-med / 2.0))
    return np.asarray(p < alpha)


@dataclass(frozen=True)
class SettlingTest:
    """Result of :func:`settling_test`.

    :param statistic: T_j at the frequency of the smallest p; :param dof: 2n, its mean under no ring.
    :param p_value: Bonferroni-corrected p value (over the frequencies tried).
    :param frequency_hz: the frequency of the smallest p.
    :param early_power_ratio: mean 2P/P_ref at that frequency in the early segments (1 without a ring).
    :param n_obs: number of periodogram ordinates behind the statistic.
    """

    statistic: float
    dof: int
    p_value: float
    frequency_hz: float
    early_power_ratio: float
    n_obs: int
    ref_dof: int = 0
    """Degrees of freedom of the three channels' references together at that frequency (3 d_ref)."""


def _segment_spectra(x: FloatArray, n_seg: int) -> FloatArray:
    """(k, n_f, 3) periodograms of the k = len(x) // n_seg consecutive segments, detrended."""
    k = x.shape[0] // n_seg
    seg = x[: k * n_seg].reshape(k, n_seg, 3)
    t = np.arange(n_seg) - (n_seg - 1) / 2.0
    seg = seg - seg.mean(axis=1, keepdims=True)
    slope = np.einsum("t,ktc->kc", t, seg) / float(t @ t)
    seg = seg - slope[:, None, :] * t[None, :, None]
    return np.abs(np.fft.rfft(seg, axis=1)) ** 2 / n_seg


def detrended_response(n_seg: int) -> FloatArray:
    """(n_seg // 2 + 1,) h_j = E[P(f_j)] / σ² of a detrended segment of white noise (σ²).

    With U (n_seg, 2) an orthonormal basis of the mean and slope that ``_segment_spectra``
    removes and e_j the Fourier vector of bin j (|e_j|² = n_seg), the detrended periodogram
    of white noise has E[P_j] = σ² |(I − UUᵀ) e_j|² / n_seg = σ² (1 − Σ_k |e_jᴴ u_k|² / n_seg).
    """
    t = np.arange(n_seg) - (n_seg - 1) / 2.0
    U = np.column_stack([np.ones(n_seg) / math.sqrt(n_seg), t / math.sqrt(float(t @ t))])
    return np.asarray(1.0 - np.sum(np.abs(np.fft.rfft(U, axis=0)) ** 2, axis=1) / n_seg, dtype=float)


def _spectra(
    window_samples: tuple[FloatArray, ...], sample_rate_hz: float, th: Thresholds
) -> tuple[list[FloatArray], FloatArray, FloatArray]:
    """(per-window segment spectra, reference (n_f, 3), reference dof per channel (n_f,))."""
    seg_s = th.settling_segment_s
    n_seg = round(seg_s * sample_rate_hz)
    if n_seg < 16:
        raise ValueError(f"settling: {sample_rate_hz:g} Hz is too slow for {seg_s:g} s segments")
    spectra = [_segment_spectra(x, n_seg) for x in window_samples if x.shape[0] >= 4 * n_seg]
    if len(spectra) < 3:
        raise ValueError(f"settling: needs at least 3 windows of {4 * seg_s:g} s or more")
    late_segments = [s[s.shape[0] // 2 :] for s in spectra]
    late = np.concatenate(late_segments).mean(axis=0)  # (n_f, 3)
    n_late = sum(x.shape[0] for x in late_segments)
    n_f = late.shape[0]
    h = detrended_response(n_seg)
    flat = late / h[:, None]
    ref = np.empty_like(late)
    ref_dof = np.empty(n_f)
    for j in range(n_f):
        near = [k for k in (j - 3, j - 2, j + 2, j + 3) if 2 <= k < n_f] or [j]
        ref[j] = h[j] * flat[near].mean(axis=0)
        ref_dof[j] = 2.0 * n_late * len(near)
    return spectra, np.where(ref > 0, ref, np.inf), ref_dof


def _bins(sample_rate_hz: float, n_f: int, segment_s: float) -> npt.NDArray[np.intp]:
    f = np.arange(n_f) / segment_s
    return np.flatnonzero((np.arange(n_f) >= 2) & (f < 0.45 * sample_rate_hz))


def frequency_p_values(
    window_samples: tuple[FloatArray, ...], sample_rate_hz: float, th: Thresholds = THRESHOLDS
) -> tuple[FloatArray, FloatArray, FloatArray, int, FloatArray]:
    """Per-frequency statistics of the test (module docstring), before the Bonferroni step.

    :returns: (f_j (Hz), T_j, p_j = F(2n, 3 d_ref(j)) tail of T_j / (2n), n, 3 d_ref(j)).
    :raises ValueError: windows too short or too slowly sampled for the test.
    """
    spectra, ref, ref_dof = _spectra(window_samples, sample_rate_hz, th)
    n_early = th.settling_early_segments
    early = np.concatenate([s[: min(n_early, s.shape[0] // 2)] for s in spectra])  # (k, n_f, 3)
    bins = _bins(sample_rate_hz, ref.shape[0], th.settling_segment_s)
    ratio = 2.0 * early[:, bins, :] / ref[None, bins, :]
    # (k, 3): an outlying sample is not a ring (module docstring)
    keep = ~broadband(ratio, th.settling_broadband_alpha)
    T = (ratio * keep[:, None, :]).sum(axis=(0, 2))
    n = max(1, int(keep.sum()))
    d_ref = 3.0 * ref_dof[bins]
    return bins / th.settling_segment_s, T, f_dist.sf(T / (2 * n), 2 * n, d_ref), n, d_ref


def settling_test(
    window_samples: tuple[FloatArray, ...], sample_rate_hz: float, th: Thresholds = THRESHOLDS
) -> SettlingTest:
    """Narrow-band early-excess test of the module docstring.

    :param window_samples: per window (n_w, 3) raw samples; :param sample_rate_hz: rate (Hz).
    :raises ValueError: windows too short or too slowly sampled for the test.
    """
    freq, T, p_bins, n, d_ref = frequency_p_values(window_samples, sample_rate_hz, th)
    j = int(np.argmin(p_bins))
    return SettlingTest(
        statistic=float(T[j]),
        dof=2 * n,
        p_value=min(1.0, float(p_bins[j]) * p_bins.size),
        frequency_hz=float(freq[j]),
        early_power_ratio=float(T[j] / (2 * n)),
        n_obs=n,
        ref_dof=int(d_ref[j]),
    )


def settling_duration(
    window_samples: tuple[FloatArray, ...],
    sample_rate_hz: float,
    frequency_hz: float,
    th: Thresholds = THRESHOLDS,
) -> tuple[float, float]:
    """(duration_s, sigma) of the ring from the decay of its narrow-band power (module docstring).

    :raises ValueError: windows too short or the decay cannot be fitted.
    """
    spectra, ref, _ = _spectra(window_samples, sample_rate_hz, th)
    seg_s = th.settling_segment_s
    j = round(frequency_hz * seg_s)
    k = min(s.shape[0] for s in spectra) // 2
    if k < 3:
        raise ValueError("settling: windows too short to follow the decay of the ring")
    a = np.stack([s[:k, j, :] / ref[j] for s in spectra])  # (m, k, 3)
    R = a.mean(axis=(0, 2))
    sd = np.maximum(R / math.sqrt(a.shape[0] * a.shape[2]), 1e-12)
    s = (np.arange(k) + 0.5) * seg_s

    def model(s: FloatArray, b: float, tau: float) -> FloatArray:
        return 1.0 + b * np.exp(-2.0 * s / tau)

    try:
        p0 = (max(R[0] - 1.0, 1e-3), 2.0)
        p, cov = curve_fit(
            model, s, R, p0=p0, sigma=sd, absolute_sigma=True, bounds=([0, 0.05], [np.inf, 1e3])
        )
    except (RuntimeError, ValueError) as exc:
        raise ValueError(f"settling: the decay of the ring could not be fitted ({exc})") from exc
    chi2_red = float(np.sum(((R - model(s, *p)) / sd) ** 2)) / max(k - 2, 1)
    tau_sigma = float(np.sqrt(max(cov[1, 1], 0.0) * max(chi2_red, 1.0)))
    return float(p[1] * th.settling_ring_decades), tau_sigma * th.settling_ring_decades


@dataclass(frozen=True)
class Settling:
    """``settling`` (module docstring)."""

    id: str = "settling"
    kind: EffectKind = "window"
    needs_table: bool = True
    parameters: tuple[ParamSpec, ...] = (ParamSpec("duration_s", "s", ()),)
    explanation: str = (
        "the table structure still rings after a move when the window starts, so the first "
        "seconds of each window carry a decaying oscillation at the structure's frequency"
    )

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        seg_s, n_early = th.settling_segment_s, th.settling_early_segments
        if ev.window_samples is None or ev.sample_rate_hz is None:
            return False, "needs the windows' samples, not only their means"
        if seg_s * ev.sample_rate_hz < 16:
            return False, f"needs at least 8 Hz sampling ({ev.sample_rate_hz:g} Hz)"
        n_min = 4 * seg_s * ev.sample_rate_hz
        if sum(x.shape[0] >= n_min for x in ev.window_samples) < 3:
            return False, f"needs at least 3 windows of {4 * seg_s:g} s or more"
        return True, (
            f"narrow-band power of the first {n_early * seg_s:g} s of each window "
            "against the windows' second halves"
        )

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        return []


SETTLING = Settling()
