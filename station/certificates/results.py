"""The certificate's results and |g| check sections from the stored fit.

Each quantity of the fitted model (``bias``, ``scale_matrix``) is stated as
``{"value", "expanded_uncertainty", "unit", "k"}`` with U = k·u_c to two significant digits
(:mod:`station.certificates.rounding`, GUM 7.2.6): u_c the combined standard uncertainty of the
budget (:meth:`station.certificates.budget.CertificateBudget.combined`) and k the quantity's
largest t_95.45 %(ν_eff), or, without a budget, u_c the fit's Type A σ and k = 2. The |g|
check states the mean and the standard deviation of e_w = |K⁻¹(ȳ_w − b)| − g_local before and
after adjustment, each to two significant digits, with U of the mean
(:func:`station.certificates.conformity.g_check_u`).
"""

from __future__ import annotations

import math
from typing import Any

from bench.fitted_model import FittedModel, GCheckSummary
from bench.limit_check import LimitCheck
from bench.uncertainty.budget import WANDER_GROUP
from station.certificates.budget import CertificateBudget
from station.certificates.conformity import G_CHECK_U_BASIS, g_check_u
from station.certificates.datasheet_units import datasheet_results
from station.certificates.rounding import expanded_quantity, round_significant
from station.certificates.statements import COVERAGE_K, NOT_STATED, RUN_MEAN_BIAS


def two_digits(value: float | None) -> float | None:
    """A statistic stated to two significant digits (half-up, :mod:`station.certificates.rounding`);
    ``None`` when absent or not finite. Printed with both digits by ``format_significant``."""
    if value is None or not math.isfinite(value):
        return None
    return round_significant(float(value))


def results_section(fit: FittedModel, budget: CertificateBudget | None) -> dict[str, Any]:
    unit = fit.channel_unit
    (u_b, k_b), (u_k, k_k) = (
        (budget.combined("bias"), budget.combined("scale_matrix"))
        if budget is not None
        else ((fit.bias_sigma, COVERAGE_K), (fit.K_sigma, COVERAGE_K))
    )
    results: dict[str, Any] = {
        "channel_unit": unit,
        "model": "raw = bias + scale_matrix · f, f the specific force in m/s²",
        "terms": list(fit.terms),
        "bias": expanded_quantity(fit.bias, u_b, unit, k_b),
        "scale_matrix": expanded_quantity(fit.K, u_k, f"{unit}/(m/s2)", k_k),
        "uncertainty_budget": budget.to_content() if budget is not None else NOT_STATED,
        "datasheet_units": datasheet_results(fit, budget),
        "residual_rms": {"value": two_digits(fit.residual_rms), "unit": unit},
        "extra": fit.extra,
    }
    return results


def bias_statements(fit: FittedModel, budget: CertificateBudget | None = None) -> list[str]:
    """The certificate's statements about which bias its bias U describes: :data:`RUN_MEAN_BIAS`
    where the fit's ``bias_reference`` is ``"run_mean"`` and the budget has no line for the
    unit's bias wander over the run (``bench.uncertainty.budget.WANDER_GROUP``); none where
    the U is the unit's long-run bias's or the reference is not stated."""
    if budget is not None and any(i.group == WANDER_GROUP for i in budget.budget.inputs):
        return []
    return [RUN_MEAN_BIAS] if fit.bias_reference == "run_mean" else []


def g_check_section(
    fit: FittedModel, g_check_n: int | None, checks: tuple[LimitCheck, ...] = ()
) -> dict[str, Any]:
    checked_u = {c.name: c.expanded_uncertainty for c in checks if c.expanded_uncertainty is not None}
    out: dict[str, Any] = {
        "description": "|K⁻¹(raw − b)| − g_local over the static windows: mean error and standard "
        "deviation with the unit's nominal scale and zero-g output (its data sheet) and with this "
        "calibration (the item itself was not adjusted)",
    }
    missing = {"before": f"{NOT_STATED}: no nominal scale known for this unit", "after": NOT_STATED}
    stated: dict[str, GCheckSummary | None] = {"before": fit.g_before, "after": fit.g_after}
    for when, g in stated.items():
        if g is None:
            out[when] = missing[when]
            continue
        out[when] = {"mean_error_m_s2": two_digits(g.mean_error_m_s2), "std_m_s2": two_digits(g.std_m_s2)}
        u_g = g_check_u(g.std_m_s2, g_check_n)
        if u_g is None and when == "after":  # a moving recording: the U its limit check carries
            u_g = checked_u.get("g_error_after")
        out[when]["expanded_uncertainty_m_s2"] = u_g if u_g is not None else NOT_STATED
        out[when]["n"] = g_check_n if g_check_n is not None else NOT_STATED
    out["uncertainty_basis"] = G_CHECK_U_BASIS
    nominal = fit.g_before.nominal if fit.g_before is not None else None
    out["before_basis"] = (
        f"nominal scale {nominal.scale:g} and zero-g output {nominal.bias:g} ({nominal.source})"
        if nominal is not None
        else "the raw output in its own physical unit"
        if fit.g_before is not None
        else NOT_STATED
    )
    return out
