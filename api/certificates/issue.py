"""After a run: diagnose it, store the fit and the diagnosis, issue the certificate.

The slow part (reading the recording and diagnosing it, :func:`analyse_run`) happens before
the write transaction opens; :func:`finish_calibration` then stores and issues in one.

The certificate number is allocated race-free by ``db.repo.certificates.issue_certificate``
(unique ``(year, serial)``, retried on conflict); the content, which names its own number,
is then completed, hashed (sha256 of the canonical JSON) and rendered to PDF inside the same
transaction, so a number is never visible without its final content.
"""

from __future__ import annotations

import datetime as dt
import importlib.util
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from api.certificates.budget import CertificateBudget, TypeBSettings, certificate_budget
from api.certificates.certificate import certificate_content
from api.certificates.conformity import limits_choice
from api.certificates.deviations import stored_actions
from api.certificates.inputs import CertificateInputs, Laboratory, RunFacts, UnitFacts
from api.certificates.pdf import render_pdf
from api.settings import Settings, placeholder_reason
from bench.calibration import NATURAL_ZERO_UNITS, calibrate_recording, select_windows
from bench.calibration.dynamic import is_dynamic
from bench.diagnosis.result import Diagnosis
from bench.diagnosis.stored import StoredDiagnosis
from bench.fitted_model import FittedModel, GCheckSummary, NominalReference
from bench.limit_check import LimitCheck
from bench.recording import Recording, read_recording
from bench.records import RunRecord
from db.models import Certificate, FitKind, Run, RunState, Unit
from db.repo.certificates import canonical_sha256, issue_certificate
from db.repo.results import add_findings, add_fit, list_findings, list_fits
from db.repo.runs import merge_params
from db.types import utc_now

DIAGNOSIS_AVAILABLE = importlib.util.find_spec("bench.calibration.diagnose") is not None
"""The diagnosis module is installed (it is optional for the service)."""


def diagnose(rec: Recording) -> Diagnosis:
    """The diagnosis of a recording (its ``calbench diagnose --json`` object by ``to_contract()``).

    :raises RuntimeError: the diagnosis module is not installed.
    :raises ValueError: the recording cannot be diagnosed (message names it).
    """
    if not DIAGNOSIS_AVAILABLE:
        raise RuntimeError("the diagnosis module (bench.calibration.diagnose) is not installed")
    from bench.calibration.diagnose import diagnose_recording

    return diagnose_recording(rec)


class CertificateRefused(ValueError):
    """A real bench's certificate cannot be issued: the laboratory's identity or the
    authorising person is not configured (the message names each setting)."""


def _configured(value: str, env: str) -> str:
    return f"not configured ({env})" if placeholder_reason(value) is not None else value.strip()


def laboratory(settings: Settings) -> Laboratory:
    """The issuing laboratory from the settings (an unset item reads "not configured (ENV)",
    which only a simulated bench's certificate can carry)."""
    return Laboratory(
        _configured(settings.lab_name, "CALBENCH_LAB_NAME"),
        _configured(settings.lab_address, "CALBENCH_LAB_ADDRESS"),
        _configured(settings.lab_location, "CALBENCH_LAB_LOCATION"),
        _configured(settings.authorized_by, "CALBENCH_AUTHORIZED_BY"),
        settings.customer_name,
        settings.customer_address,
        tuple(settings.reference_equipment),
        settings.ambient_conditions,
    )


def _table(rec: Recording) -> dict[str, Any] | None:
    t = rec.sidecar.table
    if t is None:
        return None
    return {
        "axes": [{"name": a.name, "axis": list(a.axis)} for a in t.axes],
        "mount_rotation": [list(r) for r in t.mount_rotation],
        "lever_arm_m": list(t.lever_arm_m),
    }


def _temperature(record: RunRecord) -> tuple[float, float, float] | None:
    temps = [w.temp_c_mean for w in record.windows if math.isfinite(w.temp_c_mean)]
    if not temps:
        return None
    return float(min(temps)), float(np.mean(temps)), float(max(temps))


@dataclass(frozen=True)
class RunAnalysis:
    """What a finished run's recording gave, computed outside any transaction.

    :param rec: the recording, or ``None`` when unreadable or not needed.
    :param diagnosis: the recording's diagnosis, or ``None``.
    :param note: why there is no diagnosis (empty when there is one).
    :param g_before: the |g| check with the unit's registered nominal scale (``before``
        adjustment) when the fit had none, with its ``nominal``.
    """

    rec: Recording | None
    diagnosis: Diagnosis | None
    note: str
    g_before: GCheckSummary | None = None


Nominal = tuple[float, float | None]
"""A unit's registered nominal scale (channel unit per m/s²) and zero-g output (channel unit)."""


def g_check_before(rec: Recording, nominal: Nominal) -> GCheckSummary | None:
    """The |g| check of ``rec`` with the nominal scale and zero-g output (no adjustment), with
    that nominal; ``None`` if it cannot be formed (also when a V or count unit was registered
    without its zero-g output: assuming 0 would give a meaningless check)."""
    scale, bias = nominal
    if bias is None and rec.sidecar.channel_unit not in NATURAL_ZERO_UNITS:
        return None
    try:
        cal = calibrate_recording(rec, nominal_scale=scale, nominal_bias=np.full(3, bias or 0.0))
    except ValueError:
        return None
    if cal.g_before is None:
        return None
    ref = NominalReference(scale, bias or 0.0, "unit registration")
    return GCheckSummary(cal.g_before.mean_error_m_s2, cal.g_before.std_m_s2, ref)


def analyse_recording(path: str | None, nominal: Nominal | None = None) -> RunAnalysis:
    """Read the recording at ``path``, diagnose it and, with a nominal scale, form the |g|
    check before adjustment (no database)."""
    if not path:
        return RunAnalysis(None, None, "diagnosis not performed: the run has no recording")
    try:
        rec = read_recording(path)
    except (OSError, ValueError) as exc:
        return RunAnalysis(None, None, f"diagnosis not performed: recording {path} cannot be read: {exc}")
    before = g_check_before(rec, nominal) if nominal is not None else None
    try:
        return RunAnalysis(rec, diagnose(rec), "", before)
    except (RuntimeError, ValueError) as exc:
        return RunAnalysis(rec, None, f"diagnosis not performed: {exc}", before)


def analyse_run(record: RunRecord, nominal: Nominal | None = None) -> RunAnalysis:
    """The analysis of a finished run: only a run with a fit is diagnosed; the nominal
    |g| check is formed only when the fit has no ``before`` of its own."""
    if record.calibration is None:
        return RunAnalysis(None, None, "diagnosis not performed: the run has no fit")
    if record.calibration.g_before is not None:
        nominal = None
    return analyse_recording(str(record.start.recording_path), nominal)


def store_diagnosis(s: Session, run_id: str, analysis: RunAnalysis) -> None:
    """Store the findings (``finding`` rows) and the whole diagnosis object (run params), or
    why there is none."""
    if analysis.diagnosis is None:
        merge_params(s, run_id, {"diagnosis_error": analysis.note})
        return
    add_findings(s, run_id, StoredDiagnosis.of(analysis.diagnosis).findings)
    merge_params(s, run_id, {"diagnosis": dict(analysis.diagnosis.to_contract()), "diagnosis_error": None})


def store_g_before(s: Session, run_id: str, g_before: GCheckSummary | None) -> None:
    """Add the nominal |g| check to the run's stored fit as ``g_check.before``."""
    run = s.get(Run, run_id)
    cal = run.params.get("calibration") if run is not None else None
    if g_before is None or not isinstance(cal, dict) or "before" in cal.get("g_check", {}):
        return
    g_check = {**cal.get("g_check", {}), "before": g_before.to_contract()}
    merge_params(s, run_id, {"calibration": {**cal, "g_check": g_check}})


def store_results(s: Session, record: RunRecord, analysis: RunAnalysis) -> None:
    """Store the fit (unless the run's database observer already did), the nominal |g| check
    and the diagnosis (or why there is none)."""
    if record.calibration is not None and not list_fits(s, record.run_id):
        add_fit(s, record.run_id, FitKind.STATIC, record.calibration.to_contract())
    store_g_before(s, record.run_id, analysis.g_before)
    store_diagnosis(s, record.run_id, analysis)


def unit_inputs(unit: Unit) -> UnitFacts:
    """What the certificate states about the item and its customer, from the unit's registration."""
    return UnitFacts(
        serial=unit.serial,
        model=unit.model,
        channel_unit=unit.channel_unit,
        description=unit.description,
        condition=unit.condition,
        customer_name=unit.customer_name,
        customer_address=unit.customer_address,
        received_on=unit.received_on,
        nominal_scale=unit.nominal_scale,
        nominal_bias=unit.nominal_bias,
    )


def unit_nominal(unit: Unit | None) -> Nominal | None:
    """The unit's registered nominal (scale, zero-g output), or ``None``."""
    if unit is None or unit.nominal_scale is None:
        return None
    return unit.nominal_scale, unit.nominal_bias


def g_check_count(rec: Recording) -> int | None:
    """Windows of the |g| check of a static fit (its static windows); ``None`` for a moving
    recording (whose 1 s blocks only the dynamic fit forms)."""
    if is_dynamic(rec):
        return None
    try:
        return len(select_windows(rec))
    except ValueError:
        return None


def limits_model_name(settings: Settings, model: str | None) -> str | None:
    """The unit model whose limits judge a unit registered as ``model``: ``model`` when the
    limits file has it; ``settings.limits_model`` only when the registration names no model;
    else ``None`` (:func:`api.certificates.conformity.limits_choice`).

    :raises ValueError: the limits file is unreadable or malformed (named).
    """
    choice = limits_choice(settings, model, None)
    return choice.limits.model if choice.limits is not None else None


def run_budget(
    rec: Recording | None, calibration: FittedModel, settings: Settings
) -> tuple[CertificateBudget | None, str]:
    """The uncertainty budget of a run's fit with the bench's Type B settings, or ``None`` and why not."""
    if rec is None:
        return None, "the run's recording cannot be read, so the fit's design is unknown"
    try:
        return certificate_budget(rec, calibration, TypeBSettings.of(settings)), ""
    except (KeyError, ValueError) as exc:
        return None, f"budget not formed: {exc}"


def issue_for_run(
    s: Session,
    settings: Settings,
    run_id: str,
    *,
    rec: Recording | None = None,
    diagnosis: StoredDiagnosis | None = None,
    diagnosis_note: str = "",
    temp_c: tuple[float, float, float] | None = None,
    now: dt.datetime | None = None,
) -> Certificate:
    """Issue the certificate of a completed run that has a fit.

    :param diagnosis: the run's diagnosis; ``None``: the one stored with the run, if any.
    :raises LookupError: no such run. :raises ValueError: the run has no fit or is not completed.
    :raises bench.fitted_model.ContractError: the stored fit or the stored diagnosis lacks a key
        or holds an ill-typed one (named).
    """
    run = s.get(Run, run_id)
    if run is None:
        raise LookupError(f"run {run_id} not found")
    stored = run.params.get("calibration")
    if run.state is not RunState.COMPLETED or not isinstance(stored, dict):
        raise ValueError(f"run {run_id} is {run.state.value} without a fit: no certificate can be issued")
    calibration = FittedModel.from_contract(stored, f"run {run_id}: stored fit")
    unit = s.get(Unit, run.unit_id)
    assert unit is not None
    if rec is None and run.recording_path:
        try:
            rec = read_recording(run.recording_path)
        except (OSError, ValueError):
            rec = None
    if diagnosis is None and run.params.get("diagnosis") is not None:
        diagnosis = StoredDiagnosis.from_contract(run.params["diagnosis"], f"run {run_id}: stored diagnosis")
    simulated = bool(run.params.get("sim"))
    blocking, _warnings = settings.certificate_gaps()
    if blocking and not simulated:
        raise CertificateRefused(
            f"no certificate issued for run {run_id} from a real bench: " + "; ".join(blocking)
        )
    g_local = rec.sidecar.g_local_m_s2 if rec is not None else None
    bench_file = run.params.get("bench_config")
    u_g = bench_file.get("g_local_u_m_s2") if isinstance(bench_file, dict) else None
    if isinstance(u_g, float):  # the bench file's u(g) for the g it gave the recording
        settings = settings.model_copy(update={"g_local_u_m_s2": u_g})
    budget, budget_note = run_budget(rec, calibration, settings)
    inputs = CertificateInputs(
        run=RunFacts(
            id=run.id,
            procedure=run.procedure,
            started_at=run.started_at,
            finished_at=run.finished_at,
            parameters=run.params.get("parameters", {}),
            bench=run.params.get("bench"),
            sample_gaps=run.params.get("sample_gaps", []),
            bench_config=run.params.get("bench_config"),
            actions=stored_actions(s, run_id),
        ),
        unit=unit_inputs(unit),
        calibration=calibration,
        g_local_m_s2=g_local,
        temp_c=temp_c,
        table=_table(rec) if rec is not None else None,
        diagnosis=diagnosis,
        diagnosis_note=diagnosis_note or str(run.params.get("diagnosis_error", "")),
        simulated=simulated,
        budget=budget,
        budget_note=budget_note,
        limit_checks=tuple(
            LimitCheck.from_stored(c, f"run {run_id}: limit check {i}")
            for i, c in enumerate(run.limit_checks or [])
        ),
        outcome=run.outcome,
        limits_model=limits_model_name(settings, unit.model) if run.limit_checks else None,
        limits_note="" if run.limit_checks else limits_choice(settings, unit.model, unit.channel_unit).reason,
        g_check_n=g_check_count(rec) if rec is not None else None,
    )
    now = now or utc_now()
    cert = issue_certificate(s, run_id, {"pending": run_id}, now=now)
    content = certificate_content(inputs, laboratory(settings), number=cert.number, issued_at=now)
    cert.content = content
    cert.sha256 = canonical_sha256(content)
    cert.pdf = render_pdf(content, cert.sha256)
    s.flush()
    return cert


def finish_calibration(
    s: Session, settings: Settings, record: RunRecord, analysis: RunAnalysis | None = None
) -> Certificate | None:
    """Store fit and diagnosis of a finished calibration run and issue its certificate when
    it passed (``None``: no certificate). Pass ``analysis`` from :func:`analyse_run`, computed
    before the transaction; without it the analysis runs here."""
    analysis = analysis if analysis is not None else analyse_run(record)
    store_results(s, record, analysis)
    if record.calibration is None or record.outcome is None or record.outcome.value != "PASS":
        return None
    try:
        return _issue_after_run(s, settings, record, analysis)
    except CertificateRefused as exc:
        merge_params(s, record.run_id, {"certificate_error": str(exc)})
        return None


def _issue_after_run(s: Session, settings: Settings, record: RunRecord, analysis: RunAnalysis) -> Certificate:
    return issue_for_run(
        s,
        settings,
        record.run_id,
        rec=analysis.rec,
        diagnosis=StoredDiagnosis.of(analysis.diagnosis) if analysis.diagnosis is not None else None,
        diagnosis_note=analysis.note,
        temp_c=_temperature(record),
    )


def findings_of(s: Session, run_id: str) -> list[dict[str, Any]]:
    """Stored findings of a run as dicts."""
    return [
        {
            "effect": f.effect,
            "summary": f.summary,
            "parameters": f.parameters,
            "sigma": f.sigma,
            "delta_bic": f.delta_bic,
        }
        for f in list_findings(s, run_id)
    ]
