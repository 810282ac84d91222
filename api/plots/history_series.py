"""Coefficient history of a unit: each fitted coefficient over its runs, with ±U bands.

A stored fit (:class:`bench.fitted_model.FittedModel`) carries the bias b (3,) and the scale
matrix K (3, 3) with one-sigma uncertainties of the same shapes. The dashboard plots, per
coefficient, the value of each run and U = k·σ with k = 2 (about 95 % coverage for a normal
distribution; JCGM 100:2008 §6.2), σ being the fit's Type A standard uncertainty. This is not
the certificate's U: a certificate states U = k·u_c from its GUM budget (Type A + Type B, k
from ν_eff; :mod:`station.certificates.budget`). A run whose coefficient is not finite is left out
of that coefficient's series rather than plotted as zero; a σ that is not finite gives no U.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from bench.fitted_model import FittedModel

COVERAGE_K = 2.0
"""Coverage factor of the expanded uncertainty U = k·σ."""

AXES = ("x", "y", "z")


@dataclass(frozen=True)
class HistoryPoint:
    """One calibrated run of a unit.

    :param run_id: the run.
    :param at: ISO 8601 time of the run's end (UTC).
    :param fit: its stored fit.
    :param kind: ``calibration`` (a certificate run), ``drift_check`` or ``other``.
    """

    run_id: str
    at: str
    fit: FittedModel
    kind: str = "calibration"


def _coefficients(channel_unit: str) -> list[tuple[str, str, str, str, tuple[int, ...]]]:
    """(name, label, unit, fitted quantity (``bias`` or ``K``), index) of every plotted coefficient."""
    Row = tuple[str, str, str, str, tuple[int, ...]]
    out: list[Row] = [(f"bias_{a}", f"bias {a}", channel_unit, "bias", (i,)) for i, a in enumerate(AXES)]
    per = f"{channel_unit}/(m/s²)"
    for i, a in enumerate(AXES):
        for j, b in enumerate(AXES):
            kind = "scale" if i == j else "cross-axis"
            out.append((f"K_{a}{b}", f"K {a}{b} ({kind})", per, "K", (i, j)))
    return out


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _value_sigma(fit: FittedModel, quantity: str, idx: tuple[int, ...]) -> tuple[float | None, float | None]:
    """(value, σ) of one coefficient; ``None`` where not finite."""
    value, sigma = (fit.bias, fit.bias_sigma) if quantity == "bias" else (fit.K, fit.K_sigma)
    return _finite(float(value[idx])), _finite(float(sigma[idx]))


def coefficient_history(points: Iterable[HistoryPoint], channel_unit: str) -> dict[str, Any]:
    """Series of every coefficient over a unit's runs, oldest first.

    :param points: calibrated runs (any order; sorted by ``at``).
    :param channel_unit: the unit's channel unit, for the labels.
    :returns: ``{"coverage_k", "runs": [{"run_id", "at", "kind"}], "coefficients": [{"name", "label",
        "unit", "run_index": [...], "value": [...], "U": [...]}]}``; ``U`` is ``None`` where the
        fit's σ is not finite.
    """
    pts = sorted(points, key=lambda p: p.at)
    coeffs = []
    for name, label, unit, quantity, idx in _coefficients(channel_unit):
        run_index: list[int] = []
        values: list[float] = []
        u: list[float | None] = []
        for k, p in enumerate(pts):
            v, s = _value_sigma(p.fit, quantity, idx)
            if v is None:
                continue
            run_index.append(k)
            values.append(v)
            u.append(None if s is None else COVERAGE_K * abs(s))
        coeffs.append(
            {"name": name, "label": label, "unit": unit, "run_index": run_index, "value": values, "U": u}
        )
    return {
        "coverage_k": COVERAGE_K,
        "runs": [{"run_id": p.run_id, "at": p.at, "kind": p.kind} for p in pts],
        "coefficients": coeffs,
    }
