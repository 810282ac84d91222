"""After a run: diagnose it, store the fit and the diagnosis, issue the certificate.

Everything slow happens before the write transaction opens, on the run's one
:class:`~bench.calibration.analysis.Analysis` (the recording read once and fitted once by the
verdict): :func:`prepare_run` adds the nominal |g| check and the diagnosis and forms the
certificate's uncertainty budget (for a moving table, minutes of refits); :func:`finish_calibration`
then stores and issues in one short transaction, reading neither the recording nor refitting.

The certificate number is allocated race-free by ``db.repo.certificates.issue_certificate``
(unique ``(year, serial)``, retried on conflict); the content, which names its own number,
is then completed, hashed (sha256 of the canonical JSON) and rendered to PDF inside the same
transaction, so a number is never visible without its final content.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from bench.calibration.analysis import (
    DIAGNOSIS_AVAILABLE,
    Analysis,
    Nominal,
    analyse,
    with_diagnosis,
    with_nominal,
)
from bench.diagnosis.result import Diagnosis
from bench.diagnosis.stored import StoredDiagnosis
from bench.fitted_model import ContractError, FittedModel
from bench.limit_check import LimitCheck
from bench.recording import Recording, read_recording
from bench.records import RunRecord
from db.models import Certificate, Run, RunState, Unit
from db.models import run_params as rp
from db.observer import store_fit, update_stored_fit
from db.repo.certificates import canonical_sha256, issue_certificate
from db.repo.gaps import list_gaps
from db.repo.results import add_findings, fit_contract, list_findings, set_diagnosis
from db.repo.runs import set_certificate_error
from db.types import utc_now
from station.certificates.budget import CertificateBudget, TypeBSettings, analysis_budget
from station.certificates.certificate import certificate_content
from station.certificates.conformity import limits_choice
from station.certificates.deviations import stored_actions
from station.certificates.inputs import CertificateInputs, Laboratory, RunFacts, UnitFacts
from station.certificates.pdf import render_pdf
from station.settings import Settings, placeholder_reason

__all__ = ["DIAGNOSIS_AVAILABLE", "Nominal"]


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

    :param analysis: the run's analysis (fit, nominal |g| check, diagnosis, budget's design),
        or ``None`` when the recording is missing, unreadable or cannot be fitted.
    :param note: why there is no diagnosis (empty when there is one).
    """

    analysis: Analysis | None
    note: str

    @property
    def diagnosis(self) -> Diagnosis | None:
        """The recording's diagnosis, or ``None``."""
        return self.analysis.diagnosis if self.analysis is not None else None


def certificate_settings(settings: Settings, params: dict[str, Any]) -> Settings:
    """The settings a run's certificate is issued with: the bench file's u(g) for the g it gave
    the recording (``params["bench_config"]["g_local_u_m_s2"]``), when it states one."""
    bench_file = params.get(rp.BENCH_CONFIG)
    u_g = bench_file.get("g_local_u_m_s2") if isinstance(bench_file, dict) else None
    return settings.model_copy(update={"g_local_u_m_s2": u_g}) if isinstance(u_g, float) else settings


def _complete(analysis: Analysis, nominal: Nominal | None, diagnose: bool) -> RunAnalysis:
    analysis = with_nominal(analysis, nominal)
    if diagnose:
        analysis = with_diagnosis(analysis)
    return RunAnalysis(analysis, analysis.diagnosis_note)


def form_budget(
    prepared: RunAnalysis, settings: Settings, params: dict[str, Any], stored: FittedModel | None = None
) -> tuple[CertificateBudget | None, str]:
    """The certificate's budget of the run's fit (``stored``, default the analysis's own) with
    the bench's Type B settings, or ``None`` and why not; formed once per analysis, fit values
    and settings and kept with the analysis (``station.certificates.budget.analysis_budget``), so
    the budget :func:`prepare_run` forms before the transaction is the one issued in it."""
    if prepared.analysis is None:
        return None, "the run's recording cannot be read, so the fit's design is unknown"
    if stored is None:
        try:
            stored = FittedModel.from_contract(prepared.analysis.contract(), "the run's fit")
        except ContractError as exc:
            return None, f"budget not formed: {exc}"
    tb = TypeBSettings.of(certificate_settings(settings, params))
    return analysis_budget(prepared.analysis, stored, tb)


def prepare_run(
    record: RunRecord, nominal: Nominal | None, settings: Settings, params: dict[str, Any]
) -> RunAnalysis:
    """Everything slow of a finished calibration run, before its transaction: the run's analysis
    (from the verdict; read and fitted only when the record has none) with the nominal |g| check
    when the fit has no ``before`` of its own, the diagnosis, and for a run that passed the
    certificate's budget (``params``: the run's stored parameters, for the bench file's u(g))."""
    if record.calibration is None:
        return RunAnalysis(None, "diagnosis not performed: the run has no fit")
    if record.analysis is None:
        prepared = analyse_recording(str(record.start.recording_path), nominal)
    else:
        prepared = _complete(record.analysis, nominal, diagnose=True)
    if record.state is RunState.COMPLETED:  # certified: PASS, or no limits judged it
        form_budget(prepared, settings, params)
    return prepared


def analyse_recording(
    path: str | None, nominal: Nominal | None = None, *, diagnose: bool = True
) -> RunAnalysis:
    """Read the recording at ``path``, fit it, form the nominal |g| check and (``diagnose``)
    diagnose it, for a run whose verdict left no analysis (no database)."""
    if not path:
        return RunAnalysis(None, "diagnosis not performed: the run has no recording")
    try:
        rec = read_recording(path)
    except (OSError, ValueError) as exc:
        return RunAnalysis(None, f"diagnosis not performed: recording {path} cannot be read: {exc}")
    try:
        analysis = analyse(rec)
    except ValueError as exc:
        return RunAnalysis(None, f"diagnosis not performed: {exc}")
    return _complete(analysis, nominal, diagnose)


def store_diagnosis(s: Session, run_id: str, prepared: RunAnalysis) -> None:
    """Store the findings (``finding`` rows) and the whole diagnosis object (``Run.diagnosis``),
    or why there is none (``Run.diagnosis_error``)."""
    if prepared.diagnosis is None:
        set_diagnosis(s, run_id, None, prepared.note)
        return
    add_findings(s, run_id, StoredDiagnosis.of(prepared.diagnosis).findings)
    set_diagnosis(s, run_id, prepared.diagnosis.to_contract(), None)


def store_g_before(s: Session, run_id: str, prepared: RunAnalysis) -> None:
    """Add the nominal |g| check to the run's stored fit as ``g_check.before`` (when the stored
    fit has none)."""
    g_before = prepared.analysis.g_before if prepared.analysis is not None else None
    if g_before is not None:
        update_stored_fit(s, run_id, lambda c: _with_before(c, g_before.to_contract()))


def _with_before(contract: dict[str, Any], before: dict[str, Any]) -> dict[str, Any] | None:
    g_check = contract.get("g_check")
    if not isinstance(g_check, dict) or "before" in g_check:
        return None
    return {**contract, "g_check": {**g_check, "before": before}}


def store_results(s: Session, record: RunRecord, prepared: RunAnalysis) -> None:
    """Store the fit (unless the run's database observer already did), the nominal |g| check
    and the diagnosis (or why there is none)."""
    if record.calibration is not None:
        store_fit(s, record, replace=False)
    store_g_before(s, record.run_id, prepared)
    store_diagnosis(s, record.run_id, prepared)


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


def limits_model_name(settings: Settings, model: str | None) -> str | None:
    """The unit model whose limits judge a unit registered as ``model``: ``model`` when the
    limits file has it; ``settings.limits_model`` only when the registration names no model;
    else ``None`` (:func:`station.certificates.conformity.limits_choice`).

    :raises ValueError: the limits file is unreadable or malformed (named).
    """
    choice = limits_choice(settings, model, None)
    return choice.limits.model if choice.limits is not None else None


def issue_for_run(
    s: Session,
    settings: Settings,
    run_id: str,
    *,
    prepared: RunAnalysis | None = None,
    diagnosis: StoredDiagnosis | None = None,
    diagnosis_note: str = "",
    temp_c: tuple[float, float, float] | None = None,
    now: dt.datetime | None = None,
) -> Certificate:
    """Issue the certificate of a completed run that has a fit.

    :param prepared: the run's analysis from :func:`prepare_run` or :func:`analyse_recording`,
        formed before the transaction; ``None``: the recording is read and fitted here (a run
        stored without one).
    :param diagnosis: the run's diagnosis; ``None``: the one stored with the run, if any.
    :raises LookupError: no such run. :raises ValueError: the run has no fit or is not completed.
    :raises bench.fitted_model.ContractError: the stored fit or the stored diagnosis lacks a key
        or holds an ill-typed one (named).
    """
    run = s.get(Run, run_id)
    if run is None:
        raise LookupError(f"run {run_id} not found")
    stored = fit_contract(s, run_id)
    if run.state is not RunState.COMPLETED or not isinstance(stored, dict):
        raise ValueError(f"run {run_id} is {run.state.value} without a fit: no certificate can be issued")
    calibration = FittedModel.from_contract(stored, f"run {run_id}: stored fit")
    unit = s.get(Unit, run.unit_id)
    assert unit is not None
    if prepared is None:
        prepared = analyse_recording(run.recording_path, diagnose=False)
    rec = prepared.analysis.recording if prepared.analysis is not None else None
    if diagnosis is None and run.diagnosis is not None:
        diagnosis = StoredDiagnosis.from_contract(run.diagnosis, f"run {run_id}: stored diagnosis")
    simulated = bool(run.params.get(rp.SIM))
    blocking, _warnings = settings.certificate_gaps()
    if blocking and not simulated:
        raise CertificateRefused(
            f"no certificate issued for run {run_id} from a real bench: " + "; ".join(blocking)
        )
    g_local = rec.sidecar.g_local_m_s2 if rec is not None else None
    budget, budget_note = form_budget(prepared, settings, run.params, calibration)
    settings = certificate_settings(settings, run.params)
    judged = (run.limit_checks or []) if run.outcome in ("PASS", "FAIL") else []  # withdrawn: none
    inputs = CertificateInputs(
        run=RunFacts(
            id=run.id,
            procedure=run.procedure,
            started_at=run.started_at,
            finished_at=run.finished_at,
            parameters=run.params.get(rp.PARAMETERS, {}),
            bench=run.params.get(rp.BENCH),
            sample_gaps=[dataclasses.asdict(g) for g in list_gaps(s, run_id)],
            bench_config=run.params.get(rp.BENCH_CONFIG),
            actions=stored_actions(s, run_id),
        ),
        unit=unit_inputs(unit),
        calibration=calibration,
        g_local_m_s2=g_local,
        temp_c=temp_c,
        table=_table(rec) if rec is not None else None,
        diagnosis=diagnosis,
        diagnosis_note=diagnosis_note or str(run.diagnosis_error or ""),
        simulated=simulated,
        budget=budget,
        budget_note=budget_note,
        limit_checks=tuple(
            LimitCheck.from_stored(c, f"run {run_id}: limit check {i}") for i, c in enumerate(judged)
        ),
        outcome=run.outcome,
        limits_model=limits_model_name(settings, unit.model) if judged else None,
        limits_note="" if judged else limits_choice(settings, unit.model, unit.channel_unit).reason,
        g_check_n=prepared.analysis.g_check_windows if prepared.analysis is not None else None,
    )
    now = now or utc_now()
    cert = issue_certificate(s, run_id, {"pending": run_id}, now=now)
    content = certificate_content(inputs, laboratory(settings), number=cert.number, issued_at=now)
    cert.content = content
    cert.sha256 = canonical_sha256(content)
    cert.pdf = render_pdf(content, cert.sha256, kind=calibration.kind)
    s.flush()
    return cert


def finish_calibration(
    s: Session, settings: Settings, record: RunRecord, analysis: RunAnalysis | None = None
) -> Certificate | None:
    """Store fit and diagnosis of a finished calibration run and issue its certificate when
    it completed: passed, or no limits judged it (``None``: no certificate). Pass ``analysis``
    from :func:`prepare_run`, computed before the transaction (its budget is then formed
    already); without it the analysis runs here, inside the transaction."""
    if analysis is None:
        run = s.get(Run, record.run_id)
        analysis = prepare_run(record, None, settings, dict(run.params) if run is not None else {})
    store_results(s, record, analysis)
    if record.calibration is None or record.state is not RunState.COMPLETED:
        return None
    try:
        return _issue_after_run(s, settings, record, analysis)
    except CertificateRefused as exc:
        set_certificate_error(s, record.run_id, str(exc))
        return None


def _issue_after_run(s: Session, settings: Settings, record: RunRecord, analysis: RunAnalysis) -> Certificate:
    return issue_for_run(
        s,
        settings,
        record.run_id,
        prepared=analysis,
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
