"""Coefficient history of a unit: each fitted coefficient over its runs, with ±U bands.

A calibration contract (``shared/cli-contract.md``) carries ``bias`` (3,) and
``scale_matrix`` K (3, 3) with one-sigma uncertainties of the same shapes. The dashboard
plots, per coefficient, the value of each run and U = k·σ with k = 2 (about 95 % coverage for
a normal distribution; JCGM 100:2008 §6.2), σ being the fit's Type A standard uncertainty
from the contract. This is not the certificate's U: a certificate states U = k·u_c from its
GUM budget (Type A + Type B, k from ν_eff; :mod:`api.certificates.budget`). Runs whose
contract lacks a coefficient, or whose value is not finite, are left out of that
coefficient's series rather than plotted as zero.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

COVERAGE_K = 2.0
"""Coverage factor of the expanded uncertainty U = k·σ."""

AXES = ("x", "y", "z")


@dataclass(frozen=True)
class HistoryPoint:
    """One calibrated run of a unit.

    :param run_id: the run.
    :param at: ISO 8601 time of the run's end (UTC).
    :param contract: its calibration contract dict.
    :param kind: ``calibration`` (a certificate run), ``drift_check`` or ``other``.
    """

    run_id: str
    at: str
    contract: Mapping[str, Any]
    kind: str = "calibration"


def _coefficients(channel_unit: str) -> list[tuple[str, str, str, str, tuple[int, ...]]]:
    """(name, label, unit, contract key, index) of every plotted coefficient."""
    Row = tuple[str, str, str, str, tuple[int, ...]]
    out: list[Row] = [(f"bias_{a}", f"bias {a}", channel_unit, "bias", (i,)) for i, a in enumerate(AXES)]
    per = f"{channel_unit}/(m/s²)"
    for i, a in enumerate(AXES):
        for j, b in enumerate(AXES):
            kind = "scale" if i == j else "cross-axis"
            out.append((f"K_{a}{b}", f"K {a}{b} ({kind})", per, "scale_matrix", (i, j)))
    return out


def _pick(contract: Mapping[str, Any], key: str, idx: tuple[int, ...]) -> float | None:
    value: Any = contract.get(key)
    try:
        for i in idx:
            value = value[i]
        x = float(value)
    except (TypeError, IndexError, ValueError):
        return None
    return x if math.isfinite(x) else None


def coefficient_history(points: Iterable[HistoryPoint], channel_unit: str) -> dict[str, Any]:
    """Series of every coefficient over a unit's runs, oldest first.

    :param points: calibrated runs (any order; sorted by ``at``).
    :param channel_unit: the unit's channel unit, for the labels.
    :returns: ``{"coverage_k", "runs": [{"run_id", "at", "kind"}], "coefficients": [{"name", "label",
        "unit", "run_index": [...], "value": [...], "U": [...]}]}``; ``U`` is ``None`` where the
        contract has no sigma.
    """
    pts = sorted(points, key=lambda p: p.at)
    coeffs = []
    for name, label, unit, key, rest in _coefficients(channel_unit):
        run_index: list[int] = []
        values: list[float] = []
        u: list[float | None] = []
        for k, p in enumerate(pts):
            v = _pick(p.contract, key, rest)
            if v is None:
                continue
            s = _pick(p.contract, f"{key}_sigma", rest)
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
