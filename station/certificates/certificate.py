"""The content of a calibration certificate (ISO/IEC 17025:2017 7.8.2.1 and 7.8.4.1) as JSON.

:func:`certificate_content` is pure: it takes what the run produced and returns a dict
that is hashed (``db.repo.certificates.canonical_sha256``) and rendered to PDF. The fitted
model is carried under the names of ``calbench calibrate --json`` (``bias``,
``scale_matrix``, ``residual_rms``, ``g_check``), each quantity as
``{"value", "expanded_uncertainty", "unit", "k"}`` with U = k·u_c to two significant digits
(:mod:`station.certificates.rounding`): u_c the combined standard uncertainty of the uncertainty
budget (``results.uncertainty_budget``, Type A + Type B, :mod:`station.certificates.budget`) and k
the largest of the quantity's elements' t_95.45 %(ν_eff) (2 for ν_eff = ∞); without a budget,
u_c is the fit's Type A σ and k = 2 (:mod:`station.certificates.results`). The fixed wording is in
:mod:`station.certificates.statements`, what it is built from in :mod:`station.certificates.inputs`.
"""

from __future__ import annotations

import datetime as dt
import importlib.metadata
from typing import Any

from bench.fit_kind import FitKind
from bench.planning.report import predicted_and_achieved
from bench.procedures.planned import NAME as PLANNED_STATIC
from bench.procedures.planned import TUMBLE_NAME as PLANNED_TUMBLE
from station.certificates.conformity import check_uncertainties, conformity_statement
from station.certificates.deviations import no_deviation, run_deviations, run_record_section
from station.certificates.inputs import CertificateInputs, Laboratory, UnitFacts
from station.certificates.results import bias_statements, g_check_section, results_section
from station.certificates.statements import (
    COVERAGE_STATEMENT,
    DYNAMIC_COVERAGE_STATEMENT,
    METHOD,
    NOT_REPRODUCED,
    NOT_STATED,
    ONLY_ITEM,
    SIMULATED_AMBIENT,
    SIMULATED_EQUIPMENT,
    TITLE,
    TYPE_A_ONLY_STATEMENT,
)


def _iso(value: dt.datetime | None) -> str | None:
    return None if value is None else value.isoformat()


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


def _item(unit: UnitFacts) -> dict[str, Any]:
    cu = unit.channel_unit or NOT_STATED
    return {
        "description": unit.description or "triaxial accelerometer",
        "serial": unit.serial,
        "model": _stated(unit.model),
        "channel_unit": cu,
        "nominal_scale": _nominal(unit.nominal_scale, f"{cu}/(m/s2)"),
        "nominal_zero_g_output": _nominal(unit.nominal_bias, cu),
        "condition": _stated(unit.condition),
        "adjustment": "none: the item was not adjusted; results are as found",
    }


def _customer(unit: UnitFacts, lab: Laboratory) -> dict[str, Any]:
    name, address = unit.customer_name, unit.customer_address
    source = "unit registration"
    if not name and not address and (lab.default_customer_name or lab.default_customer_address):
        name, address, source = lab.default_customer_name, lab.default_customer_address, "laboratory default"
    if not name and not address:
        source = "not given to the laboratory"
    return {"name": _stated(name), "address": _stated(address), "source": source}


def _findings(inp: CertificateInputs) -> dict[str, Any]:
    if inp.diagnosis is None:
        return {"performed": False, "note": inp.diagnosis_note or "diagnosis not available", "findings": []}
    findings = [
        {"effect": f.effect, "summary": f.summary, "parameters": f.parameters, "sigma": f.sigma}
        for f in inp.diagnosis.findings
    ]
    note = (
        "the first-order model explains the recording to its noise; no unmodelled effect was found"
        if not findings
        else "effects beyond the first-order model were found; see findings (opinion, 7.8.7)"
    )
    return {"performed": True, "note": note, "findings": findings}


def sample_integrity(gaps: Any, n_resumes: int = 0) -> str:
    """One line on samples lost while recording (``RunFacts.sample_gaps``: the stored gap records)
    and on the recording's interruptions (``n_resumes``: times the run was continued after one)."""
    cut = (
        f"; the recording was interrupted and continued {n_resumes} time{'s' if n_resumes > 1 else ''} "
        "from its last complete window (the time between is not in it; see the deviations)"
        if n_resumes
        else ""
    )
    if not isinstance(gaps, list) or not gaps:
        return ("every sample the DAQ produced was recorded (no gap)" if not cut else "no sample gap") + cut
    known = [g.get("n_lost") for g in gaps if isinstance(g, dict)]
    n = sum(int(v) for v in known if isinstance(v, int))
    unknown = " (and an unknown number across a DAQ restart)" if any(v is None for v in known) else ""
    spoiled = sum(1 for g in gaps if isinstance(g, dict) and g.get("window_index") is not None)
    return (
        f"{n} samples lost{unknown} in {len(gaps)} gaps, each recorded where it happened; "
        f"{spoiled} fell inside a window, which was re-measured; no window with a gap was used{cut}"
    )


def bench_configuration(identity: Any) -> str:
    """One line naming the bench file a run was made with (``RunFacts.bench_config``)."""
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
    procedure = run.procedure
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
            "parameters": run.parameters,
            "deviations": [*run_deviations(run), *inp.deviations] or [no_deviation(run)],
            "sampling": "not applicable",
            **(
                {
                    "planned_U_k2": predicted_and_achieved(
                        run.parameters, inp.calibration.K, inp.calibration.K_sigma, inp.calibration.bias_sigma
                    )
                }
                if procedure in (PLANNED_STATIC, PLANNED_TUMBLE)
                else {}
            ),
        },
        "item": _item(unit),
        "dates": {
            "received": _stated(unit.received_on.isoformat() if unit.received_on else None),
            "calibration_start": _iso(run.started_at),
            "calibration_end": _iso(run.finished_at),
            "issued": _iso(issued_at),
        },
        "run_id": run.id,
        "run_record": run_record_section(run),
        "bench": _stated(run.bench),
        "conditions": {
            "sensor_temperature": temp,
            "g_local_m_s2": _stated(inp.g_local_m_s2),
            "table": _stated(inp.table),
            "sample_integrity": sample_integrity(
                run.sample_gaps, sum(1 for a in run.actions if a.action == "resume")
            ),
            "bench_configuration": bench_configuration(run.bench_config),
            "ambient": SIMULATED_AMBIENT if inp.simulated else _stated(lab.ambient_conditions),
        },
        "reference_equipment": list(SIMULATED_EQUIPMENT)
        if inp.simulated
        else list(lab.reference_equipment) or [NOT_STATED],
        "software": software(),
        "results": results_section(inp.calibration, inp.budget),
        "g_check": g_check_section(inp.calibration, inp.g_check_n, inp.limit_checks),
        "uncertainty_statement": (
            DYNAMIC_COVERAGE_STATEMENT if inp.calibration.kind is FitKind.MOVING else COVERAGE_STATEMENT
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
            inp.limits_note,
        ),
        "traceability": traceability,
        "statements": [ONLY_ITEM, *bias_statements(inp.calibration, inp.budget), NOT_REPRODUCED],
        "authorized_by": lab.authorized_by,
        "authorization": "Authorised for issue by the person named above; the SHA-256 of this content "
        "identifies the authorised version.",
        "external_providers": "none",
        "end": "End of certificate",
    }
