"""The statement of conformity (ISO/IEC 17025:2017 7.8.6) from a run's limit checks.

The expanded uncertainties the checks carry are the certificate's own (:func:`check_uncertainties`),
so the U beside each verdict is the U of the results table:

* ``bias_i``, ``scale_i`` (K_ii): U = k·u_c of the parameter, k the quantity's coverage factor
  (the largest t_95.45 %(ν_eff) of its elements,
  :meth:`station.certificates.budget.CertificateBudget.combined`), rounded to two significant
  digits (GUM 7.2.6);
* ``cross_axis_ij`` = K_ij / K_ii: u² = (u(K_ij)/K_ii)² + (K_ij·u(K_ii)/K_ii²)² (first-order
  propagation, the two taken uncorrelated), k of the scale matrix;
* ``g_error_after``, the mean of e_w = |f̂_w| − g_local over the n windows (or 1 s blocks):
  u = s(e)/√n (Type A, GUM 4.2.3), k = 2 — conservative: the fit of b and K to the same
  windows draws the mean towards 0 (over simulated static-12 recordings |mean| stays far
  inside U, ``tests/station/certificates/test_certificate_conformity.py``).

Without a budget, u is the fit's Type A σ and k = 2 (as in the results table).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from bench.fitted_model import FittedModel
from bench.limit_check import LimitCheck
from bench.limits import AXES, DECISION_RULES, LimitsChoice, choose_limits, load_limits
from db.repo.units import get_unit_by_serial
from station.certificates.budget import CertificateBudget
from station.certificates.rounding import round_significant
from station.settings import Settings

COVERAGE_K = 2.0
G_CHECK_U_BASIS = (
    "u = s(e)/√n, s(e) the standard deviation of the n per-window errors |f̂| − g (Type A), k = 2; an "
    "upper bound, as the least-squares fit itself draws the mean error towards 0"
)


def _u_k(fit: FittedModel, budget: CertificateBudget | None) -> tuple[np.ndarray, float, np.ndarray, float]:
    if budget is not None:
        (u_b, k_b), (u_k, k_k) = budget.combined("bias"), budget.combined("scale_matrix")
        return np.asarray(u_b, float), k_b, np.asarray(u_k, float), k_k
    return np.asarray(fit.bias_sigma, float), COVERAGE_K, np.asarray(fit.K_sigma, float), COVERAGE_K


def _u2(x: float) -> float:
    return round_significant(x) if math.isfinite(x) and x > 0 else float(x)


def g_check_u(std_m_s2: float | None, n: int | None) -> float | None:
    """U (k = 2, two significant digits) of the |g| check's mean error over ``n`` windows,
    ``None`` when ``n`` < 2 or the standard deviation is not a finite number."""
    if n is None or n < 2 or std_m_s2 is None or not math.isfinite(std_m_s2):
        return None
    return _u2(COVERAGE_K * float(std_m_s2) / math.sqrt(float(n)))


def check_uncertainties(
    fit: FittedModel, budget: CertificateBudget | None, g_check_n: int | None = None
) -> dict[str, float]:
    """Expanded uncertainty U (two significant digits) of each value the limits check, by limit
    name (``bench.limits.checked_values``), from a fit and its budget.

    :param g_check_n: the number of windows (or 1 s blocks) of the |g| check; ``None``: its U
        is not stated.
    """
    K = np.asarray(fit.K, float)
    u_b, k_b, u_K, k_K = _u_k(fit, budget)
    out: dict[str, float] = {}
    for i, a in enumerate(AXES):
        out[f"bias_{a}"] = _u2(k_b * float(u_b[i]))
        out[f"scale_{a}"] = _u2(k_K * float(u_K[i, i]))
        for j in range(3):
            if i != j:
                kii, kij = K[i, i], K[i, j]
                u = math.hypot(u_K[i, j] / kii, kij * u_K[i, i] / kii**2)
                out[f"cross_axis_{a}{AXES[j]}"] = _u2(k_K * u)
    u_g = g_check_u(fit.g_after.std_m_s2, g_check_n)
    if u_g is not None:
        out["g_error_after"] = u_g
    return out


def limits_choice(settings: Settings, model: str | None, channel_unit: str | None) -> LimitsChoice:
    """The limits that judge a unit registered as ``model`` (``bench.limits.choose_limits`` on
    the bench's limits file, ``settings.limits_model`` only for a unit that names no model),
    or why none do; ``channel_unit`` ``None``: not known yet.

    :raises ValueError: the limits file is unreadable or malformed (named).
    """
    return choose_limits(load_limits(settings.limits_file), model, channel_unit, settings.limits_model)


def conformity_warning(settings: Settings, model: str | None, channel_unit: str | None) -> str | None:
    """What an operator is told before a run of such a unit starts when its certificate will
    make no statement of conformity; ``None`` when limits apply."""
    try:
        choice = limits_choice(settings, model, channel_unit)
    except ValueError as exc:
        return f"the limits file cannot be read, so the bench will refuse the run: {exc}"
    if choice.limits is not None:
        return None
    known = f" (limits are configured for: {', '.join(choice.known_models)})" if choice.known_models else ""
    return f"no statement of conformity will be made: {choice.reason}{known}"


def unit_warnings(session: Session, settings: Settings, serial: str) -> list[str]:
    """:func:`conformity_warning` for the unit registered as ``serial`` (a serial not yet
    registered names no model), as a list for an API answer."""
    unit = get_unit_by_serial(session, serial)
    model, channel_unit = (unit.model, unit.channel_unit) if unit is not None else (None, None)
    warning = conformity_warning(settings, model, channel_unit)
    return [warning] if warning else []


def _verdict_word(passed: bool) -> str:
    return "conforms" if passed else "does not conform"


def conformity_statement(
    checks: Sequence[LimitCheck],
    outcome: str | None,
    model: str | None,
    rule: str | None,
    uncertainties: Mapping[str, float] | None = None,
    no_limits_reason: str = "",
) -> dict[str, Any]:
    """The certificate's conformity section from the run's stored limit checks and its stored
    outcome.

    :param uncertainties: the certificate's own U of each checked value
        (:func:`check_uncertainties` with its budget), stated in place of the stored one; the
        verdicts and acceptance intervals are the stored ones (under guarded acceptance they
        were formed with this same U).
    :param no_limits_reason: why no limits applied (``LimitsChoice.reason``), stated when there
        are no checks.

    The statement's verdict is the run's outcome; it is checked against the checks, so a
    certificate can never state another verdict than the checks it lists.

    :raises ValueError: the outcome disagrees with the checks.
    """
    if not checks:
        why = no_limits_reason or f"no limits are configured for its model {model or 'not stated'}"
        return {
            "requested": False,
            "statement": "No statement of conformity is made: no specification limits apply to this "
            f"unit ({why}).",
            "decision_rule": "not applicable",
            "checks": [],
        }
    rule = rule or checks[0].rule
    all_pass = all(c.passed for c in checks)
    if outcome not in ("PASS", "FAIL") or (outcome == "PASS") != all_pass:
        which = "all" if all_pass else "not all"
        raise ValueError(f"the run's outcome {outcome!r} disagrees with its limit checks ({which} pass)")
    rows = []
    for c in checks:
        rows.append(
            {
                "quantity": c.name,
                "value": c.value,
                "expanded_uncertainty": (uncertainties or {}).get(c.name, c.expanded_uncertainty),
                "unit": c.unit,
                "low": c.low,
                "high": c.high,
                "acceptance_low": c.acceptance_low,
                "acceptance_high": c.acceptance_high,
                "verdict": _verdict_word(c.passed),
            }
        )
    n_bad = sum(1 for c in checks if not c.passed)
    what = (
        f"the item conforms to the specification of model {model or 'not stated'}: all {len(checks)} "
        "checked values are inside their acceptance intervals"
        if all_pass
        else f"the item does not conform to the specification of model {model or 'not stated'}: "
        f"{n_bad} of {len(checks)} checked values are outside their acceptance intervals"
    )
    return {
        "requested": True,
        "statement": f"Statement of conformity: {'PASS' if all_pass else 'FAIL'} — {what}.",
        "outcome": "PASS" if all_pass else "FAIL",
        "specification": f"limits of unit model {model or 'not stated'}",
        "decision_rule": DECISION_RULES.get(rule, rule),
        "rule": rule,
        "g_check_uncertainty": G_CHECK_U_BASIS,
        "checks": rows,
    }
