"""Exports of a fitted model with the noise a Kalibr YAML needs, from the run's Allan curve.

Kalibr's accelerometer noise parameters, from the overlapping Allan deviation σ(τ) of a static
stretch (``api.plots.run_series.allan_series``, channel units), converted with K_ii to m/s²
(IEEE Std 952 Annex C; Kalibr wiki "IMU Noise Model"):

* noise density N = σ(τ₀)·√τ₀ at the shortest τ (white noise: σ(τ) = N/√τ), m/s²/√Hz;
* random walk K ≤ σ(τ_m)·√(3/τ_m) at the longest τ (random walk: σ(τ) = K·√(τ/3)), m/s³/√Hz,
  an upper bound where the curve has not reached its +½ slope;

each the largest of the three channels (Kalibr has one value per sensor). Kalibr's
``update_rate`` is the recording's nominal ``sample_rate_hz`` (the series carries it); a
series without it gives the rate of its time stamps rounded to six significant digits.

An export of a certified run states the certificate's number, date of issue and expanded
uncertainties of b and K (:func:`certified_uncertainty`); any other export the fit's own 1σ.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.export import FORMATS, Uncertainty, to_c_header, to_imucal, to_json, to_kalibr
from bench.fitted_model import FittedModel


def kalibr_noise(allan: Mapping[str, Any], fit: FittedModel) -> tuple[float, float, float]:
    """(sample rate Hz, noise density m/s²/√Hz, random walk m/s³/√Hz) from an Allan series.

    :raises ValueError: the series is too short or holds no finite value.
    """
    taus = np.asarray(allan["taus_s"], float)
    adev = np.asarray(allan["adev"], float)
    K = np.asarray(fit.K, float)
    if taus.size < 2 or adev.shape != (3, taus.size):
        raise ValueError("the Allan curve is too short to give Kalibr's noise parameters")
    if allan.get("sample_rate_hz") is not None:
        rate = float(allan["sample_rate_hz"])
    else:
        span = float(allan["end_s"]) - float(allan["start_s"])
        rate = _six_digits((int(allan["n_samples"]) - 1) / span) if span > 0 else math.nan
    scale = np.abs(np.diag(K))[:, None]
    sig = adev / scale  # m/s2
    density = float(np.nanmax(sig[:, 0] * math.sqrt(taus[0])))
    walk = float(np.nanmax(sig[:, -1] * math.sqrt(3.0 / taus[-1])))
    if not (math.isfinite(density) and math.isfinite(walk) and math.isfinite(rate)):
        raise ValueError("the Allan curve gives no finite noise values")
    return rate, density, walk


def _six_digits(x: float) -> float:
    return float(f"{x:.6g}") if math.isfinite(x) and x > 0 else math.nan


def certified_uncertainty(number: str, issued_at: dt.datetime, content: Mapping[str, Any]) -> Uncertainty:
    """The expanded uncertainties of b and K a certificate states (``results.bias`` and
    ``results.scale_matrix``: ``{"value", "expanded_uncertainty", "unit", "k"}``), with its number
    and date of issue.

    :raises ValueError: the certificate's results lack them or hold other shapes (named).
    """
    try:
        bias, K = content["results"]["bias"], content["results"]["scale_matrix"]
        u_b = np.asarray(bias["expanded_uncertainty"], float)
        u_K = np.asarray(K["expanded_uncertainty"], float)
        k_b, k_K = float(bias["k"]), float(K["k"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(
            f"certificate {number}: its results hold no readable uncertainties ({exc})"
        ) from None
    if u_b.shape != (3,) or u_K.shape != (3, 3):
        raise ValueError(f"certificate {number}: uncertainties of shapes {u_b.shape} and {u_K.shape}")
    basis = (
        f"expanded uncertainties U = k·u_c of certificate {number} (coverage probability about 95 %, "
        "as its uncertainty statement says)"
    )
    return Uncertainty(
        (float(u_b[0]), float(u_b[1]), float(u_b[2])),
        tuple((float(r[0]), float(r[1]), float(r[2])) for r in u_K),
        k_b,
        k_K,
        number,
        issued_at.date().isoformat(),
        basis,
    )


def export_text(
    fmt: str,
    fit: FittedModel,
    allan: Mapping[str, Any] | None,
    source: str,
    uncertainty: Uncertainty | None = None,
) -> str:
    """The export ``fmt`` of a fit (``allan``: the run's Allan series, needed by ``kalibr``).

    :param uncertainty: what the export states for b and K; default the fit's own 1σ.
    :raises ValueError: unknown format, a bad model, or ``kalibr`` without an Allan curve.
    """
    if fmt == "imucal":
        return to_imucal(fit, source, uncertainty)
    if fmt == "c-header":
        return to_c_header(fit, source, uncertainty)
    if fmt == "json":
        return to_json(fit, source, uncertainty)
    if fmt == "kalibr":
        if allan is None:
            raise ValueError(
                "the Kalibr export needs the run's Allan curve (a static stretch of the recording)"
            )
        rate, density, walk = kalibr_noise(allan, fit)
        return to_kalibr(fit, sample_rate_hz=rate, noise_density_m_s2_sqrt_hz=density,
                         random_walk_m_s3_sqrt_hz=walk, source=source, uncertainty=uncertainty)  # fmt: skip
    raise ValueError(f"unknown export format {fmt!r}; known: {', '.join(FORMATS)}")
