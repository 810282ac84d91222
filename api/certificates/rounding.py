"""Expanded uncertainty and consistent rounding for certificates (GUM 7.2.6, ILAC-P14).

U = k·u, reported with two significant digits; the value is rounded to the same decimal
place as the last digit of U (GUM 7.2.6: "it is usually sufficient to quote U with at
most two significant digits", and the result to the same place). Rounding is half-up on
the decimal representation, via :class:`decimal.Decimal`, so 0.0125 -> 0.013 and never
suffers binary artefacts.
"""

from __future__ import annotations

import math
from decimal import ROUND_HALF_UP, Decimal
from typing import Any

import numpy as np

SIGNIFICANT_DIGITS = 2


def round_expanded(value: float, sigma: float, k: float = 2.0) -> tuple[float, float]:
    """``(value_rounded, U_rounded)`` with U = k·sigma to two significant digits.

    :param value: the estimate.
    :param sigma: its standard uncertainty (>= 0, finite).
    :param k: coverage factor.
    :raises ValueError: non-finite value or sigma, or a negative sigma.
    """
    value, sigma, k = float(value), float(sigma), float(k)  # numpy scalars' repr is not a number
    if not (math.isfinite(value) and math.isfinite(sigma)) or sigma < 0:
        raise ValueError(f"cannot round value {value!r} with standard uncertainty {sigma!r}")
    u_expanded = k * sigma
    if u_expanded == 0.0:
        return value, 0.0
    d = Decimal(repr(u_expanded))
    exponent = d.adjusted() - (SIGNIFICANT_DIGITS - 1)  # place of the last kept digit
    quantum = Decimal(1).scaleb(exponent)
    u_r = d.quantize(quantum, rounding=ROUND_HALF_UP)
    if u_r.adjusted() > d.adjusted():  # 9.96 -> 10: keep two significant digits
        quantum = Decimal(1).scaleb(exponent + 1)
        u_r = d.quantize(quantum, rounding=ROUND_HALF_UP)
    v_r = Decimal(repr(float(value))).quantize(quantum, rounding=ROUND_HALF_UP)
    return float(v_r), float(u_r)


def round_significant(x: float, digits: int = SIGNIFICANT_DIGITS) -> float:
    """``x`` to ``digits`` significant digits, half-up on its decimal representation (0.125 -> 0.13).

    :raises ValueError: ``x`` not finite.
    """
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot round {x!r} to {digits} significant digits")
    if x == 0.0:
        return 0.0
    d = Decimal(repr(x))
    r = d.quantize(Decimal(1).scaleb(d.adjusted() - (digits - 1)), rounding=ROUND_HALF_UP)
    return float(r)


def format_significant(x: float, digits: int = SIGNIFICANT_DIGITS) -> str:
    """``x`` rounded by :func:`round_significant` and printed with all ``digits`` significant
    digits, trailing zeros kept: 2.0e-5 -> ``"2.0e-05"``, 0.1 -> ``"0.10"``, 12 -> ``"12"``.

    :raises ValueError: ``x`` not finite.
    """
    r = round_significant(x, digits)
    return "0" if r == 0.0 else f"{r:#.{digits}g}".rstrip(".")


def expanded_quantity(values: Any, sigmas: Any, unit: str, k: float = 2.0) -> dict[str, Any]:
    """A quantity (scalar, vector or matrix) as ``{"value", "expanded_uncertainty", "unit", "k"}``.

    ``values`` and ``sigmas`` have one shape; each element is rounded by :func:`round_expanded`.

    :raises ValueError: shapes differ, or an element cannot be rounded.
    """
    v = np.asarray(values, dtype=float)
    s = np.asarray(sigmas, dtype=float)
    if v.shape != s.shape:
        raise ValueError(f"value shape {v.shape} and uncertainty shape {s.shape} differ")
    pairs = [round_expanded(float(a), float(b), k) for a, b in zip(v.ravel(), s.ravel(), strict=True)]
    vr = np.array([p[0] for p in pairs]).reshape(v.shape)
    ur = np.array([p[1] for p in pairs]).reshape(v.shape)
    return {"value": vr.tolist(), "expanded_uncertainty": ur.tolist(), "unit": unit, "k": k}
