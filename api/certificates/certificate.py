"""The content of a calibration certificate (ISO/IEC 17025:2017 7.8.2.1 and 7.8.4.1) as JSON.

:func:`certificate_content` is pure: it takes what the run produced and returns a dict
that is hashed (``db.repo.certificates.canonical_sha256``) and rendered to PDF. The fitted
model is carried under the names of ``calbench calibrate --json`` (``bias``,
``scale_matrix``, ``residual_rms``, ``g_check``), each quantity as
``{"value", "expanded_uncertainty", "unit", "k"}`` with U = k·u_c to two significant digits
(:mod:`api.certificates.rounding`): u_c the combined standard uncertainty of the uncertainty
budget (``results.uncertainty_budget``, Type A + Type B, :mod:`api.certificates.budget`) and k
the largest of the quantity's elements' t_95.45 %(ν_eff) (2 for ν_eff = ∞); without a budget,
u_c is the fit's Type A σ and k = 2.
"""

from __future__ import annotations

import datetime as dt
import importlib.metadata
import math
from dataclasses import dataclass, field
from typing import Any

from api.certificates.budget import combined
from api.certificates.conformity import G_CHECK_U_BASIS, check_uncertainties, conformity_statement, g_check_u
from api.certificates.datasheet_units import datasheet_results
from api.certificates.rounding import expanded_quantity, round_significant

TITLE = "Calibration Certificate"
COVERAGE_K = 2.0
COVERAGE_STATEMENT = (
    "The reported expanded uncertainty is the combined standard uncertainty multiplied by the coverage "
    "factor k, which for a normal distribution corresponds to a coverage probability of approximately "
    "95 %; k = t_95.45 %(ν_eff) with the effective degrees of freedom ν_eff from the Welch–Satterthwaite "
    "formula, k = 2 for ν_eff = ∞. The standard uncertainty was determined in accordance with the GUM "
    "(JCGM 100:2008): Type A from the within-window noise of the recording (batch means) and the scatter "
    "between windows; Type B from the table angles, the levelling of the table base, the local gravity "
    "value, the DAQ gain and offset and the unit's temperature coefficients over the run's temperature "
    "changes, propagated by linearisation of the fit (uncertainty budget)."
)
DYNAMIC_COVERAGE_STATEMENT = COVERAGE_STATEMENT.replace(
    "Type A from the within-window noise of the recording (batch means) and the scatter between windows",
    "Type A from the sample noise of the moving-table fit and its correlation (sandwich covariance)",
).replace("propagated by linearisation of the fit", "propagated by refitting the changed recording")
"""The statement of a moving-table (``dynamic-batch``) fit with a budget."""
TYPE_A_ONLY_STATEMENT = (
    "The reported expanded uncertainty is the standard uncertainty multiplied by the coverage "
    "factor k = 2, which for a normal distribution corresponds to a coverage probability of "
    "approximately 95 %. The standard uncertainty was determined in accordance with the GUM "
    "(JCGM 100:2008): Type A only, from the within-window noise of the recording (batch means) and "
    "the scatter between windows; no Type B budget could be formed ({reason})."
)
REQUIRED_ITEMS = {
    "7.8.2.1 a title": "title",
    "7.8.2.1 b laboratory name": "laboratory.name",
    "7.8.2.1 b laboratory address": "laboratory.address",
    "7.8.2.1 c location": "location",
    "7.8.2.1 d unique identification": "number",
    "7.8.2.1 d end": "end",
    "7.8.2.1 e customer name": "customer.name",
    "7.8.2.1 e customer address": "customer.address",
    "7.8.2.1 f method": "method.description",
    "7.8.2.1 g item description": "item.description",
    "7.8.2.1 g item identification": "item.serial",
    "7.8.2.1 g item condition": "item.condition",
    "7.8.2.1 h date of receipt": "dates.received",
    "7.8.2.1 i date of calibration": "dates.calibration_start",
    "7.8.2.1 j date of issue": "dates.issued",
    "7.8.2.1 k sampling": "method.sampling",
    "7.8.2.1 l results relate to the item": "statements",
    "7.8.2.1 m results with units": "results.bias.unit",
    "7.8.2.1 n deviations": "method.deviations",
    "7.8.2.1 o authorisation": "authorized_by",
    "7.8.2.1 p external providers": "external_providers",
    "7.8.4.1 a uncertainty": "results.bias.expanded_uncertainty",
    "7.8.4.1 b conditions: temperature": "conditions.sensor_temperature",
    "7.8.4.1 b conditions: local g": "conditions.g_local_m_s2",
    "7.8.4.1 b conditions: ambient": "conditions.ambient",
    "7.8.4.1 c reference standards": "reference_equipment",
    "7.8.2.1 f software version": "software.version",
    "7.8.2.1 f procedure version": "method.procedure_version",
    "7.8.4.1 c traceability": "traceability",
    "7.8.4.1 d before adjustment": "g_check.before",
    "7.8.4.1 d after adjustment": "g_check.after",
    "7.8.4.1 e conformity": "conformity",
    "7.8.4.1 f opinions": "diagnosis.note",
}
"""Each ISO/IEC 17025:2017 item a certificate must carry, and where it is in the content
(dotted path); every one is filled, with :data:`NOT_STATED` where the laboratory gave nothing."""

SIMULATED_EQUIPMENT = (
    "simulated three-axis rate table (sim://, calbench's table simulator): no calibration status",
    "simulated DAQ (Modbus-TCP simulator): no calibration status",
)
SIMULATED_AMBIENT = "simulated bench: no ambient conditions"
NOT_STATED = "not stated"
"""What a certificate says where the laboratory did not give an item (never a null)."""
ONLY_ITEM = "The results relate only to the item calibrated."
NOT_REPRODUCED = (
    "This certificate shall not be reproduced except in full without the approval of the laboratory."
)
METHOD = {
    "static-12": "static multi-position (12 orientations, tumble test on a three-axis table, IEEE Std 1293 "
    "principle); per-channel weighted least squares of raw = b + K·f",
    "rate-1axis": "single-axis rate table; static poses for b and K, rate windows for the lever arm",
    "oscillation-2axis": "two-axis quasi-harmonic oscillation",
}


@dataclass(frozen=True)
class CertificateInputs:
    """What a certificate is built from.

    :param run: ``{"id", "procedure", "started_at", "finished_at", "parameters", "bench"}`` and
        ``"sample_gaps"`` (the run's gap records, absent or empty: none) and ``"bench_config"``
        (the bench file's identity, ``bench.bench_config.BenchConfig.identity``).
    :param unit: ``{"serial", "model", "channel_unit"}`` and the registration
        (``description``, ``condition``, ``customer_name``, ``customer_address``,
        ``received_on`` ISO date, ``nominal_scale``, ``nominal_bias``), ``None`` where not given.
    :param calibration: the ``calibrate --json`` contract.
    :param g_local_m_s2: local gravity used (m/s²), ``None`` when unknown.
    :param temp_c: (min, mean, max) sensor temperature over the windows (°C), or ``None``.
    :param table: table description (axes, mount, lever arm) from the sidecar, or ``None``.
    :param diagnosis: the ``diagnose --json`` object, or ``None`` when not run.
    :param diagnosis_note: why there is no diagnosis, when there is none.
    :param simulated: the bench was simulated (results are then not traceable).
    :param deviations: additions to / deviations from the method (7.8.2.1 n).
    :param budget: the uncertainty budget (``api.certificates.budget.certificate_budget``), or
        ``None`` (Type A only, k = 2).
    :param budget_note: why there is no budget, when there is none.
    :param limit_checks: the run's stored limit checks (``bench.records.LimitCheck`` as dicts,
        with U and the acceptance interval of the decision rule); empty: no limits applied.
    :param outcome: the run's stored outcome (``PASS``/``FAIL``), which the conformity
        statement must agree with.
    :param limits_model: the unit model whose limits judged the run.
    :param g_check_n: windows (or 1 s blocks) of the |g| check, for the U of its mean; ``None``
        when not known (U not stated).
    """

    run: dict[str, Any]
    unit: dict[str, Any]
    calibration: dict[str, Any]
    g_local_m_s2: float | None
    temp_c: tuple[float, float, float] | None = None
    table: dict[str, Any] | None = None
    diagnosis: dict[str, Any] | None = None
    diagnosis_note: str = ""
    simulated: bool = False
    deviations: list[str] = field(default_factory=list)
    budget: dict[str, Any] | None = None
    budget_note: str = ""
    limit_checks: tuple[dict[str, Any], ...] = ()
    outcome: str | None = None
    limits_model: str | None = None
    g_check_n: int | None = None


@dataclass(frozen=True)
class Laboratory:
    """Who issues: name, address, location of the work, who authorises (7.8.2.1 b, c, o), the
    customer of units registered without one (an in-house laboratory's own department), the
    bench's reference standards with their calibration status (7.8.4.1 c) and the ambient
    conditions (7.8.4.1 b)."""

    name: str
    address: str
    location: str
    authorized_by: str
    default_customer_name: str = ""
    default_customer_address: str = ""
    reference_equipment: tuple[str, ...] = ()
    ambient_conditions: str = ""


def _iso(value: Any) -> str | None:
    if value is None:
        return None
    return value.isoformat() if isinstance(value, dt.datetime) else str(value)


def _stated(value: Any) -> Any:
    """``value``, or :data:`NOT_STATED` when it is ``None`` or blank."""
    return NOT_STATED if value is None or (isinstance(value, str) and not value.strip()) else value


def _nominal(value: Any, unit: str) -> dict[str, Any]:
    """A nominal value with its unit; "not stated" carries no unit."""
    stated = _stated(value)
    return {"value": stated, "unit": "" if stated == NOT_STATED else unit}


def software() -> dict[str, str]:
    """The software that acquired, fitted and reported (name and installed version)."""
    try:
        version = importlib.metadata.version("calbench")
    except importlib.metadata.PackageNotFoundError:
        version = NOT_STATED
    return {"name": "calbench", "version": version}


def _item(unit: dict[str, Any]) -> dict[str, Any]:
    cu = unit.get("channel_unit") or NOT_STATED
    return {
        "description": unit.get("description") or "triaxial accelerometer",
        "serial": unit.get("serial"),
        "model": _stated(unit.get("model")),
        "channel_unit": cu,
        "nominal_scale": _nominal(unit.get("nominal_scale"), f"{cu}/(m/s2)"),
        "nominal_zero_g_output": _nominal(unit.get("nominal_bias"), cu),
        "condition": _stated(unit.get("condition")),
        "adjustment": "none: the item was not adjusted; results are as found",
    }


def _customer(unit: dict[str, Any], lab: Laboratory) -> dict[str, Any]:
    name, address = unit.get("customer_name"), unit.get("customer_address")
    source = "unit registration"
    if not name and not address and (lab.default_customer_name or lab.default_customer_address):
        name, address, source = lab.default_customer_name, lab.default_customer_address, "laboratory default"
    if not name and not address:
        source = "not given to the laboratory"
    return {"name": _stated(name), "address": _stated(address), "source": source}


def _two_digits(value: Any) -> float | None:
    """A statistic stated to two significant digits (half-up, :mod:`api.certificates.rounding`);
    ``None`` when absent or not finite. Printed with both digits by ``format_significant``."""
    if value is None or not math.isfinite(float(value)):
        return None
    return round_significant(float(value))


def _results(cal: dict[str, Any], budget: dict[str, Any] | None) -> dict[str, Any]:
    unit = str(cal.get("channel_unit", ""))
    for key in ("bias", "bias_sigma", "scale_matrix", "scale_matrix_sigma"):
        if key not in cal:
            raise ValueError(f"calibration has no {key!r}: cannot state the result")
    (u_b, k_b), (u_k, k_k) = (
        (combined(budget, "bias"), combined(budget, "scale_matrix"))
        if budget is not None
        else ((cal["bias_sigma"], COVERAGE_K), (cal["scale_matrix_sigma"], COVERAGE_K))
    )
    results: dict[str, Any] = {
        "channel_unit": unit,
        "model": "raw = bias + scale_matrix · f, f the specific force in m/s²",
        "terms": list(cal.get("terms", ["bias", "scale_matrix"])),
        "bias": expanded_quantity(cal["bias"], u_b, unit, k_b),
        "scale_matrix": expanded_quantity(cal["scale_matrix"], u_k, f"{unit}/(m/s2)", k_k),
        "uncertainty_budget": budget if budget is not None else NOT_STATED,
        "datasheet_units": datasheet_results(cal, budget),
        "residual_rms": {"value": _two_digits(cal.get("residual_rms")), "unit": unit},
        "extra": cal.get("extra", {}),
    }
    return results


def _g_check(
    cal: dict[str, Any], g_check_n: int | None, checks: tuple[dict[str, Any], ...] = ()
) -> dict[str, Any]:
    checked_u = {
        c["name"]: c.get("expanded_uncertainty") for c in checks if c.get("expanded_uncertainty") is not None
    }
    g = cal.get("g_check", {})
    out: dict[str, Any] = {
        "description": "|K⁻¹(raw − b)| − g_local over the static windows: mean error and standard "
        "deviation, before adjustment (nominal scale) and after (this calibration)",
    }
    missing = {"before": f"{NOT_STATED}: no nominal scale known for this unit", "after": NOT_STATED}
    for when in ("before", "after"):
        if isinstance(g.get(when), dict):
            out[when] = {k: _two_digits(v) for k, v in g[when].items() if k != "nominal"}
            u_g = g_check_u(g[when].get("std_m_s2"), g_check_n)
            if u_g is None and when == "after":  # a moving recording: the U its limit check carries
                u_g = checked_u.get("g_error_after")
            out[when]["expanded_uncertainty_m_s2"] = u_g if u_g is not None else NOT_STATED
            out[when]["n"] = g_check_n if g_check_n is not None else NOT_STATED
        else:
            out[when] = missing[when]
    out["uncertainty_basis"] = G_CHECK_U_BASIS
    nominal = g.get("before", {}).get("nominal") if isinstance(g.get("before"), dict) else None
    out["before_basis"] = (
        f"nominal scale {nominal['scale']:g} and zero-g output {nominal['bias']:g} ({nominal['source']})"
        if isinstance(nominal, dict)
        else "the raw output in its own physical unit"
        if isinstance(g.get("before"), dict)
        else NOT_STATED
    )
    return out


def _findings(inp: CertificateInputs) -> dict[str, Any]:
    if inp.diagnosis is None:
        return {"performed": False, "note": inp.diagnosis_note or "diagnosis not available", "findings": []}
    findings = [
        {
            "effect": f.get("effect"),
            "summary": f.get("summary"),
            "parameters": f.get("parameters", {}),
            "sigma": f.get("sigma", {}),
        }
        for f in inp.diagnosis.get("findings", [])
    ]
    note = (
        "the first-order model explains the recording to its noise; no unmodelled effect was found"
        if not findings
        else "effects beyond the first-order model were found; see findings (opinion, 7.8.7)"
    )
    return {"performed": True, "note": note, "findings": findings}


def sample_integrity(gaps: Any) -> str:
    """One line on samples lost while recording (``run["sample_gaps"]``: GapRecord objects)."""
    if not isinstance(gaps, list) or not gaps:
        return "every sample the DAQ produced was recorded (no gap)"
    known = [g.get("n_lost") for g in gaps if isinstance(g, dict)]
    n = sum(int(v) for v in known if isinstance(v, int))
    unknown = " (and an unknown number across a DAQ restart)" if any(v is None for v in known) else ""
    spoiled = sum(1 for g in gaps if isinstance(g, dict) and g.get("window_index") is not None)
    return (
        f"{n} samples lost{unknown} in {len(gaps)} gaps, each recorded where it happened; "
        f"{spoiled} fell inside a window, which was re-measured; no window with a gap was used"
    )


def bench_configuration(identity: Any) -> str:
    """One line naming the bench file a run was made with (``run["bench_config"]``)."""
    if not isinstance(identity, dict) or not identity.get("name"):
        return "not stated"
    sha = str(identity.get("sha256", ""))[:12]
    g = identity.get("g_local_m_s2")
    u = identity.get("g_local_u_m_s2")
    gravity = ""
    if isinstance(g, float) and isinstance(u, float):
        source = identity.get("g_local_source", "source not stated")
        gravity = f"; local g {g} m/s² (u = {u:.2g} m/s², {source})"
    return f"bench file {identity['name']!r} version {identity.get('version')} (SHA-256 {sha}…){gravity}"


def certificate_content(
    inp: CertificateInputs, lab: Laboratory, *, number: str, issued_at: dt.datetime
) -> dict[str, Any]:
    """The certificate as a JSON-able dict (keys named after the 17025 items they satisfy).

    :raises ValueError: the calibration lacks a quantity or holds a non-finite one.
    """
    run, unit = inp.run, inp.unit
    procedure = str(run.get("procedure", ""))
    traceability = (
        "SIMULATED BENCH: the table, DAQ and unit were simulated; these results are not "
        "metrologically traceable and are for demonstration and testing only."
        if inp.simulated
        else "Traceable to the SI through the calibrated reference standards of the bench: table angle "
        "encoders, DAQ voltage reference, thermometer, and the local gravity value stated under conditions."
    )
    temp: dict[str, float] | str = "not measured"
    if inp.temp_c is not None:
        lo, mean, hi = inp.temp_c
        temp = {"min_c": round(lo, 2), "mean_c": round(mean, 2), "max_c": round(hi, 2)}
    return {
        "title": TITLE,
        "number": number,
        "laboratory": {"name": lab.name, "address": lab.address},
        "location": lab.location,
        "customer": _customer(unit, lab),
        "method": {
            "procedure": procedure,
            "procedure_version": f"{procedure} as implemented by calbench {software()['version']}",
            "description": METHOD.get(procedure, procedure),
            "parameters": run.get("parameters", {}),
            "deviations": list(inp.deviations) or ["none"],
            "sampling": "not applicable",
        },
        "item": _item(unit),
        "dates": {
            "received": _stated(unit.get("received_on")),
            "calibration_start": _iso(run.get("started_at")),
            "calibration_end": _iso(run.get("finished_at")),
            "issued": _iso(issued_at),
        },
        "run_id": run.get("id"),
        "bench": _stated(run.get("bench")),
        "conditions": {
            "sensor_temperature": temp,
            "g_local_m_s2": _stated(inp.g_local_m_s2),
            "table": _stated(inp.table),
            "sample_integrity": sample_integrity(run.get("sample_gaps")),
            "bench_configuration": bench_configuration(run.get("bench_config")),
            "ambient": SIMULATED_AMBIENT if inp.simulated else _stated(lab.ambient_conditions),
        },
        "reference_equipment": list(SIMULATED_EQUIPMENT)
        if inp.simulated
        else list(lab.reference_equipment) or [NOT_STATED],
        "software": software(),
        "results": _results(inp.calibration, inp.budget),
        "g_check": _g_check(inp.calibration, inp.g_check_n, inp.limit_checks),
        "uncertainty_statement": (
            DYNAMIC_COVERAGE_STATEMENT
            if inp.calibration.get("method") == "dynamic-batch"
            else COVERAGE_STATEMENT
        )
        if inp.budget is not None
        else TYPE_A_ONLY_STATEMENT.format(reason=inp.budget_note or "no budget given"),
        "diagnosis": _findings(inp),
        "conformity": conformity_statement(
            inp.limit_checks,
            inp.outcome,
            inp.limits_model,
            None,
            check_uncertainties(inp.calibration, inp.budget, inp.g_check_n) if inp.limit_checks else None,
        ),
        "traceability": traceability,
        "statements": [ONLY_ITEM, NOT_REPRODUCED],
        "authorized_by": lab.authorized_by,
        "authorization": "Authorised for issue by the person named above; the SHA-256 of this content "
        "identifies the authorised version.",
        "external_providers": "none",
        "end": "End of certificate",
    }
