"""The dwell rule: how long to average a static window.

The noise of a window mean of length T is σ_A(T) (the Allan deviation is the rms change of
consecutive T-means, IEEE 952 C.1). It falls while white noise dominates (σ ∝ T^−1/2) and
stops falling where bias instability, rate random walk or drift take over. The dwell is
the averaging time τ* where that happens:

* the minimum of the fitted noise model σ²(τ) = 3Q²/τ² + N²/τ + (0.664B)² + K²τ/3 + R²τ²/2
  (:mod:`bench.estimation.noise_terms`) within the τ range the record supports. For white
  noise plus rate random walk alone, d/dτ (N²/τ + K²τ/3) = 0 gives τ* = √3·N/K;
* if the model has no interior minimum because it flattens onto a bias-instability floor,
  the first τ at which σ comes within ``FLAT_FACTOR`` of that floor (longer buys < 5 %);
* if it is still falling at the longest τ measured, that τ, flagged ``floor_reached=False``:
  the record is too short to show the floor.

Also reported per channel: where the curve departs from the white line N/√τ by √2 (the
other terms have grown as large as the white one), a common simpler rule.

For all channels together the dwell minimises the summed model variance Σ_c σ_c²(τ), the
noise power of the mean vector (channels in one unit). Pure: numbers in, dataclasses out.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar

from bench.estimation.allan import AllanResult
from bench.estimation.noise_terms import BI_FACTOR, NoiseTerms, fit_noise_model

FloatArray = npt.NDArray[np.float64]

FLAT_FACTOR = 1.05
"""On a flat floor, the dwell is where σ_A is within 5 % of the floor."""

WHITE_DEPARTURE_FACTOR = math.sqrt(2.0)
"""σ_A / (N/√τ) at which the curve is said to leave the white-noise line."""


@dataclass(frozen=True)
class ChannelDwell:
    """Dwell of one channel.

    :param channel: channel index.
    :param dwell_s: recommended averaging time (s).
    :param adev_at_dwell: model σ_A at the dwell, the noise of a window mean (unit of the data).
    :param floor_reached: False if the curve was still falling at the longest τ measured.
    :param white_departure_s: τ where σ_A = √2·N/√τ (NaN if not within the measured range).
    :param reason: one sentence.
    """

    channel: int
    dwell_s: float
    adev_at_dwell: float
    floor_reached: bool
    white_departure_s: float
    reason: str


@dataclass(frozen=True)
class DwellRecommendation:
    """One dwell for all channels and the per-channel values behind it."""

    dwell_s: float
    reason: str
    floor_reached: bool
    per_channel: tuple[ChannelDwell, ...]


VarianceFn = Callable[[float], float]


def _argmin_log(func: VarianceFn, lo_s: float, hi_s: float) -> tuple[float, bool]:
    """τ in [lo, hi] minimising func(τ) (grid in log τ, refined with bounded Brent), and
    whether the minimum is interior (False: at the upper end, still falling)."""
    grid = np.logspace(math.log10(lo_s), math.log10(hi_s), 400)
    values = np.array([func(t) for t in grid])
    i = int(np.argmin(values))
    if i == grid.size - 1:
        return hi_s, False
    if i == 0:
        return lo_s, True
    res = minimize_scalar(
        lambda u: func(math.exp(u)),
        bounds=(math.log(grid[i - 1]), math.log(grid[i + 1])),
        method="bounded",
        options={"xatol": 1e-10},
    )
    return float(math.exp(res.x)), True


def _dwell_for_variance(f: VarianceFn, lo_s: float, hi_s: float, floor_var: float) -> tuple[float, bool, str]:
    """Dwell for a model variance function: (dwell_s, floor_reached, rule used)."""
    t_star, interior = _argmin_log(f, lo_s, hi_s)
    if interior:
        return t_star, True, "minimum of the fitted Allan curve"
    if floor_var > 0 and f(hi_s) <= FLAT_FACTOR**2 * floor_var:
        grid = np.logspace(math.log10(lo_s), math.log10(hi_s), 2000)
        ok = np.array([f(t) for t in grid]) <= FLAT_FACTOR**2 * floor_var
        return float(grid[int(np.argmax(ok))]), True, "within 5 % of the flat bias-instability floor"
    return hi_s, False, "still falling at the longest τ measured: the record is too short to show the floor"


def channel_dwell(
    fit: NoiseTerms, channel: int, tau_lo_s: float, tau_hi_s: float, name: str | None = None
) -> ChannelDwell:
    """Dwell of one channel from its fitted noise terms, searched within [tau_lo_s, tau_hi_s]."""
    c2 = fit.coefficients**2

    def var(t: float) -> float:
        return float(fit.model_adev(np.array([t]))[0] ** 2)

    dwell_s, reached, rule = _dwell_for_variance(var, tau_lo_s, tau_hi_s, c2[2] * BI_FACTOR**2)
    white_dep = math.nan
    if c2[1] > 0:
        grid = np.logspace(math.log10(tau_lo_s), math.log10(tau_hi_s), 2000)
        excess = np.array([var(t) * t / c2[1] for t in grid])
        i0 = int(np.argmin(excess))  # past any quantisation-dominated start
        above = i0 + np.flatnonzero(excess[i0:] >= WHITE_DEPARTURE_FACTOR**2)
        if above.size:
            white_dep = float(grid[above[0]])
    sigma = math.sqrt(var(dwell_s))
    label = name or f"channel {channel}"
    reason = f"{label}: dwell {dwell_s:.3g} s, {rule}; the window mean then has noise σ_A = {sigma:.3g}"
    return ChannelDwell(channel, dwell_s, sigma, reached, white_dep, reason)


def recommend_dwell_s(
    result: AllanResult,
    fits: tuple[NoiseTerms, ...] | None = None,
    channel_names: tuple[str, ...] | None = None,
) -> DwellRecommendation:
    """Dwell time for static windows from an Allan analysis of a static record.

    :param result: Allan deviation of the static record, c channels.
    :param fits: noise terms per channel; fitted here (:func:`fit_noise_model`) if ``None``.
    :param channel_names: names for the reason text (default ``ch0``, ``ch1``, …).
    :returns: :class:`DwellRecommendation`; ``reason`` is one or two sentences to store with a run.
    """
    if fits is None:
        fits = fit_noise_model(result)
    if len(fits) != result.n_channels:
        raise ValueError(f"{len(fits)} noise fits for {result.n_channels} channels")
    names = channel_names or tuple(f"ch{c}" for c in range(result.n_channels))
    lo, hi = float(result.taus_s[0]), float(result.taus_s[-1])
    per = tuple(channel_dwell(f, c, lo, hi, names[c]) for c, f in enumerate(fits))

    def total_var(t: float) -> float:
        return float(sum(f.model_adev(np.array([t]))[0] ** 2 for f in fits))

    floor_var = float(sum((f.coefficients[2] * BI_FACTOR) ** 2 for f in fits))
    dwell_s, reached, rule = _dwell_for_variance(total_var, lo, hi, floor_var)
    each = ", ".join(f"{names[p.channel]} {p.dwell_s:.3g} s" for p in per)
    reason = (
        f"dwell {dwell_s:.3g} s: {rule} (summed over {', '.join(names)}; per channel {each}); "
        f"Allan analysis of {result.n_samples} samples at {result.sample_rate_hz:g} Hz, τ {lo:.3g}-{hi:.3g} s"
    )
    return DwellRecommendation(dwell_s=dwell_s, reason=reason, floor_reached=reached, per_channel=per)
