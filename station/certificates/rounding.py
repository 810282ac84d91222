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


def _round_at(x: Decimal, place: int) -> Decimal:
    """``x`` half-up (ties away from zero) to a multiple of 10^place."""
    return x.quantize(Decimal(1).scaleb(place), rounding=ROUND_HALF_UP)


def _fixed(x: Decimal, place: int) -> str:
    """``x`` (already a multiple of 10^place) in fixed notation, ``max(0, −place)`` decimals."""
    s = f"{x:f}" if place < 0 else f"{x.scaleb(0).to_integral_value():f}"
    return "0" + s[2:] if s.startswith("-0") and not any(c in "123456789" for c in s) else s


def format_with_uncertainty(value: float, u_expanded: float) -> str:
    """``"value ± U"``: the one rule for every value with an uncertainty (dashboard and
    certificate; the dashboard's ``fmtU`` in ``api/static/uncertainty.js`` gives the same
    strings). U to two significant digits, the value rounded to the decimal place of U's last
    digit (GUM 7.2.6), both in fixed notation: ``(1.49987, 4.3e-6)`` -> ``"1.4998700 ± 0.0000043"``,
    ``(1234.5, 96)`` -> ``"1235 ± 96"``, ``(0.5, 9.96)`` -> ``"1 ± 10"``. Rounding is half-up on
    the shortest decimal representation (0.0125 -> 0.013). U = 0: the value as given; a value or
    U that is not finite: ``"–"``.

    :raises ValueError: ``u_expanded`` negative.
    """
    value, u_expanded = float(value), float(u_expanded)
    if not (math.isfinite(value) and math.isfinite(u_expanded)):
        return "–"
    if u_expanded < 0:
        raise ValueError(f"expanded uncertainty {u_expanded!r} is negative")
    if u_expanded == 0.0:
        return f"{value!r} ± 0"
    u = Decimal(repr(u_expanded))
    place = u.adjusted() - (SIGNIFICANT_DIGITS - 1)
    u_r = _round_at(u, place)
    if u_r.adjusted() > u.adjusted():  # 9.96 -> 10: two significant digits, one place up
        place += 1
        u_r = _round_at(u, place)
    v_r = _round_at(Decimal(repr(value)), place)
    return f"{_fixed(v_r, place)} ± {_fixed(u_r, place)}"


def value_and_u(value: float, u_expanded: float) -> tuple[str, str]:
    """The two halves of :func:`format_with_uncertainty` (``"–"`` twice when not finite)."""
    text = format_with_uncertainty(value, u_expanded)
    value_s, _, u_s = text.partition(" ± ")
    return value_s, u_s or "–"
