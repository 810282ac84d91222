"""The drift test: is a unit's re-measured model the same as its certificate's, within the uncertainties?

Test per coefficient c (the 3 biases and 9 elements of K):

    |Δc| > k · sqrt(u_cert(c)² + u_check(c)² + u_rep(c)²),   Δc = c_check − c_cert

with u_check the standard uncertainty of the check's fit (Type A) and u_cert the part of the
certificate's uncertainty that is not common to both runs. A certificate's u_c = U/k holds the
bench's Type B inputs (:data:`BENCH_COMMON_GROUPS`: table angle encoders, base levelling,
local gravity value, DAQ gain and offset); a check on the same bench measures through the
same encoders, base, g value and DAQ, so their errors are the same in both fits and cancel in
Δc (GUM 5.2: fully correlated inputs). On the same bench u_cert is therefore the root sum of
squares of the budget's other lines: the Type A line and the unit's temperature-coefficient
lines. Counting the common ones would widen a V unit's bias limit ≈ 2.5× (u_c 2.0e-5 V,
Type A 7.9e-6 V) and hide real drift below ≈ 0.4 mg. Without a budget the certificate's U/k
is Type A already; when the check ran on another bench (or the certificate's bench is not
known) nothing cancels and u_cert = U/k. u_rep is the unit's
run-to-run bias repeatability (biases only): each fit estimates the bias its own run saw,
which includes the run's mean of the slow bias wander (bias instability); no single run
can separate it, so neither fit's σ contains it, yet it differs between two runs of an
unchanged unit. Without it an ADXL-class unit (40 µg wander, 200 s correlation time) was
flagged in 13 % of unchanged pairs at a stated 3.2 % (tests/station/drift/test_drift_false_alarm.py).
A moving certificate's budget may carry that wander as its own line
(:data:`~bench.uncertainty.budget.WANDER_GROUP`); on the same bench u_cert leaves it out, since
u_rep already counts both runs' share (on another bench U/k keeps it: a little wide).
A unit is flagged when any coefficient exceeds its limit.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.estimation.static_design import PARAMETER_NAMES
from bench.fitted_model import FittedModel
from bench.uncertainty.budget import WANDER_GROUP

BENCH_COMMON_GROUPS = ("table angle", "base levelling", "local gravity", "DAQ gain", "DAQ offset")
"""Budget groups (prefixes of ``TypeBInput.group``) whose errors are the same in every run on one
bench: the table's angle encoders and base, the local gravity value, the DAQ's gain and offset."""


def _bench_common(group: str) -> bool:
    return any(group.startswith(g) for g in BENCH_COMMON_GROUPS)


def reference_uncertainty(cert: dict[str, Any], name: str, *, same_bench: bool) -> tuple[np.ndarray, str]:
    """u_cert of ``"bias"`` (3,) or ``"scale_matrix"`` (3, 3) in the drift test, and its basis.

    Same bench with a budget: sqrt of the sum of squares of the budget's lines outside
    :data:`BENCH_COMMON_GROUPS` (Type A, temperature coefficients) and outside the unit's bias
    wander over the run (in u_rep); otherwise U/k.

    :raises ValueError: the budget lacks one of the quantity's parameters.
    """
    q = cert["results"][name]
    u_k = np.asarray(q["expanded_uncertainty"], dtype=float) / float(q["k"])
    budget = cert["results"].get("uncertainty_budget")
    if not isinstance(budget, dict):
        return u_k, "U/k (the certificate states Type A only)"
    if not same_bench:
        return u_k, "U/k (Type A and Type B: the check ran on another bench, or the certificate's is unknown)"
    names = PARAMETER_NAMES[:3] if name == "bias" else PARAMETER_NAMES[3:]
    u = []
    for p in names:
        if p not in budget["quantities"]:
            raise ValueError(f"certificate budget has no {p!r}")
        lines = budget["quantities"][p]["contributions"]
        kept = [
            float(c["contribution"])
            for c in lines
            if not _bench_common(str(c["group"])) and str(c["group"]) != WANDER_GROUP
        ]
        u.append(math.sqrt(sum(x**2 for x in kept)))
    basis = (
        "budget lines not common to both runs (Type A, temperature); same bench: "
        + ", ".join(BENCH_COMMON_GROUPS)
        + " cancel in the difference"
    )
    return np.array(u).reshape(u_k.shape), basis


def compare(
    cert: dict[str, Any],
    check: FittedModel,
    k: float,
    *,
    bias_repeatability: Any = None,
    same_bench: bool = False,
) -> dict[str, Any]:
    """Compare a check's fit with a certificate's content.

    :param bias_repeatability: (3,) standard deviation of the change of each channel's bias
        between two runs of an unchanged unit (channel units), or ``None`` (zero).
    :param same_bench: the check ran on the certificate's bench, so the bench-common Type B
        contributions of its budget cancel (:func:`reference_uncertainty`); ``False`` keeps U/k.

    :returns: ``{"k", "false_alarm_probability", "reference_uncertainty", "coefficients": [...],
        "flagged", "max_ratio"}`` (the probability that an unchanged unit is flagged, for
        independent normal errors; what u_reference contains and why); each coefficient has
        name, unit, reference, check, delta, u_reference, u_certificate (U/k), u_check,
        u_repeatability, limit, exceeded.
    :raises ValueError: a quantity missing or of another shape.
    """
    rows: list[dict[str, Any]] = []
    bases: dict[str, str] = {}
    u_rep_bias = np.zeros(3) if bias_repeatability is None else np.abs(np.asarray(bias_repeatability, float))
    if u_rep_bias.shape != (3,) or not np.all(np.isfinite(u_rep_bias)):
        raise ValueError(f"bias repeatability must be 3 finite values, got {bias_repeatability!r}")
    res = cert["results"]
    fitted = {"bias": (check.bias, check.bias_sigma), "scale_matrix": (check.K, check.K_sigma)}
    for name, (value, sigma) in fitted.items():
        q = res[name]
        ref = np.asarray(q["value"], dtype=float)
        u_cert = np.asarray(q["expanded_uncertainty"], dtype=float) / float(q["k"])
        u_ref, bases[name] = reference_uncertainty(cert, name, same_bench=same_bench)
        val = np.asarray(value, dtype=float)
        u_val = np.asarray(sigma, dtype=float)
        u_rep = u_rep_bias if name == "bias" else np.zeros_like(val)
        if ref.shape != val.shape or u_val.shape != val.shape:
            raise ValueError(f"{name}: certificate shape {ref.shape}, check shape {val.shape}")
        for idx in np.ndindex(ref.shape):
            delta = float(val[idx] - ref[idx])
            limit = k * math.hypot(float(u_ref[idx]), float(u_val[idx]), float(u_rep[idx]))
            rows.append(
                {
                    "name": f"{name}[{','.join(map(str, idx))}]",
                    "unit": q["unit"],
                    "reference": float(ref[idx]),
                    "check": float(val[idx]),
                    "delta": delta,
                    "u_reference": float(u_ref[idx]),
                    "u_certificate": float(u_cert[idx]),
                    "u_check": float(u_val[idx]),
                    "u_repeatability": float(u_rep[idx]),
                    "limit": limit,
                    "exceeded": abs(delta) > limit,
                }
            )
    ratios = [abs(r["delta"]) / r["limit"] for r in rows if r["limit"] > 0]
    p_one = math.erfc(k / math.sqrt(2.0))  # P(|z| > k) for one unchanged coefficient
    return {
        "k": k,
        "false_alarm_probability": 1.0 - (1.0 - p_one) ** len(rows),
        "reference_uncertainty": {"same_bench": same_bench, **bases},
        "coefficients": rows,
        "flagged": any(r["exceeded"] for r in rows),
        "max_ratio": max(ratios) if ratios else None,
    }
