"""How long to dwell at each static pose, and why (stored with the run).

The mean of a static window is worth averaging only while its Allan deviation still falls:
at the curve's minimum τ_min the white noise has been averaged down to the bias-instability
floor, and a longer dwell buys nothing but drift (docs/methods.md §1; IEEE Std 952 Annex C). The
dwell is therefore τ_min of the unit's Allan curve, taken from

1. the unit's last Allan characterisation, when one is given (``source = "allan"``), or
2. a static noise window the run records first (``source = "noise_window"``);

in both cases the recommendation of :func:`bench.estimation.dwell.recommend_dwell_s`
(minimum of the fitted Allan noise model), clipped to ``[min_dwell_s, max_dwell_s]``. When
the curve is still falling at the longest τ the window allowed, the floor was not reached
and the reason says so.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from bench.estimation.allan import AllanResult, averaging_factors, overlapping_allan
from bench.estimation.dwell import recommend_dwell_s
from bench.records import DwellChoice

DEFAULT_MIN_DWELL_S = 5.0
DEFAULT_MAX_DWELL_S = 300.0


def tau_at_floor_s(allan: AllanResult) -> tuple[float, bool]:
    """τ (s) where the worst channel's Allan deviation is lowest, and whether that is a true minimum.

    :returns: (τ_min, reached): ``reached`` is False when the minimum is the longest τ.
    """
    idx = np.argmin(allan.adev, axis=0)  # (c,) index of each channel's minimum
    worst = int(np.max(idx))
    return float(allan.taus_s[worst]), worst < allan.taus_s.size - 1


def choose_dwell(
    allan: AllanResult,
    source: str,
    min_dwell_s: float = DEFAULT_MIN_DWELL_S,
    max_dwell_s: float = DEFAULT_MAX_DWELL_S,
) -> DwellChoice:
    """The dwell from an Allan curve.

    :param allan: overlapping Allan deviation of the three accelerometer channels.
    :param source: ``"allan"`` or ``"noise_window"``, stored with the choice.
    """
    tau_s, _ = tau_at_floor_s(allan)
    rec = recommend_dwell_s(allan, channel_names=("ax", "ay", "az")[: allan.n_channels])
    dwell_s, why, reached = float(rec.dwell_s), str(rec.reason), bool(rec.floor_reached)
    clipped = min(max(dwell_s, min_dwell_s), max_dwell_s)
    if clipped != dwell_s:
        why += f"; {dwell_s:.3g} s clipped to [{min_dwell_s:g}, {max_dwell_s:g}] s"
    origin = "the unit's last Allan characterisation" if source == "allan" else "this run's noise window"
    sigma_min = float(np.max(np.min(allan.adev, axis=0)))
    return DwellChoice(
        dwell_s=float(clipped),
        source=source,
        reason=f"dwell {clipped:.3g} s from {origin}: {why}",
        details={
            "tau_floor_s": tau_s,
            "floor_reached": "yes" if reached else "no",
            "adev_floor": sigma_min,
            "n_samples": float(allan.n_samples),
        },
    )


def dwell_from_noise_window(
    accel: npt.ArrayLike,
    sample_rate_hz: float,
    min_dwell_s: float = DEFAULT_MIN_DWELL_S,
    max_dwell_s: float = DEFAULT_MAX_DWELL_S,
) -> DwellChoice:
    """The dwell from a static noise window of raw samples.

    :param accel: (n, 3) raw accelerometer samples of one static window.
    :param sample_rate_hz: their rate (Hz).
    :raises ValueError: too few samples for an Allan curve (fewer than 10 s worth, or < 100).
    """
    a = np.asarray(accel, dtype=float)
    if a.ndim != 2 or a.shape[0] < max(100, int(10 * sample_rate_hz)):
        raise ValueError(
            f"noise window too short for an Allan curve: {a.shape[0]} samples at "
            f"{sample_rate_hz:g} Hz (need >= 10 s and >= 100 samples)"
        )
    allan = overlapping_allan(a, sample_rate_hz, "octave")
    return choose_dwell(allan, "noise_window", min_dwell_s, max_dwell_s)


def longest_noise_window_dwell_s(
    window_s: float,
    sample_rate_hz: float,
    min_dwell_s: float = DEFAULT_MIN_DWELL_S,
    max_dwell_s: float = DEFAULT_MAX_DWELL_S,
) -> float:
    """The longest dwell (s) :func:`dwell_from_noise_window` can choose from a noise window of
    ``window_s`` s at ``sample_rate_hz``: the recommendation lies in the τ range of the window's
    octave Allan curve, so it is at most its largest τ,

        τ_max = 2^⌊log2(⌊(n − 1)/2⌋)⌋ / f_s,   n = round(window_s · f_s),

    clipped to ``[min_dwell_s, max_dwell_s]`` as the choice is (60 s at 250 Hz or 1 kHz:
    16.384 s). It is also the choice whenever the curve is still falling at that τ (white
    noise dominating the window), the usual case for a MEMS unit.

    :raises ValueError: a window too short for an Allan curve (fewer than 3 samples).
    """
    m = averaging_factors(round(window_s * sample_rate_hz), sample_rate_hz, "octave")
    return float(min(max(float(m[-1]) / sample_rate_hz, min_dwell_s), max_dwell_s))


def fixed_dwell(dwell_s: float, why: str = "given by the operator") -> DwellChoice:
    """A dwell given explicitly."""
    if not (np.isfinite(dwell_s) and dwell_s > 0):
        raise ValueError(f"dwell_s must be finite and > 0, got {dwell_s}")
    return DwellChoice(dwell_s=float(dwell_s), source="fixed", reason=f"dwell {dwell_s:g} s {why}")
