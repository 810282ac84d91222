"""After a run: store the fit and the diagnosis, issue the certificate (one transaction each).

The certificate number is allocated race-free by ``db.repo.certificates.issue_certificate``
(unique ``(year, serial)``, retried on conflict); the content, which names its own number,
is then completed, hashed (sha256 of the canonical JSON) and rendered to PDF inside the same
transaction, so a number is never visible without its final content.
"""

from __future__ import annotations

import datetime as dt
import importlib.util
import math
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from api.certificates.certificate import CertificateInputs, Laboratory, certificate_content
from api.certificates.pdf import render_pdf
from api.settings import Settings
from bench.recording import Recording, read_recording
from bench.records import RunRecord
from db.models import Certificate, FitKind, Run, Unit
from db.repo.certificates import canonical_sha256, issue_certificate
from db.repo.results import add_findings, add_fit, list_findings
from db.repo.runs import merge_params
from db.types import utc_now

DIAGNOSIS_AVAILABLE = importlib.util.find_spec("bench.diagnose_recording") is not None
"""The diagnosis module is installed (it is optional for the service)."""


def diagnose(rec: Recording) -> dict[str, Any]:
    """The ``calbench diagnose --json`` object of a recording.

    :raises RuntimeError: the diagnosis module is not installed.
    :raises ValueError: the recording cannot be diagnosed (message names it).
    """
    if not DIAGNOSIS_AVAILABLE:
        raise RuntimeError("the diagnosis module (bench.diagnose_recording) is not installed")
    from bench.diagnose_recording import diagnose_recording

    return dict(diagnose_recording(rec).to_contract())


def laboratory(settings: Settings) -> Laboratory:
    """The issuing laboratory from the settings."""
    return Laboratory(settings.lab_name, settings.lab_address, settings.lab_location, settings.authorized_by)


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


def store_results(s: Session, record: RunRecord, rec: Recording | None) -> tuple[dict[str, Any] | None, str]:
    """Store the fit and, when possible, the diagnosis of a finished run.

    :returns: (diagnosis contract or ``None``, why there is none).
    """
    if record.calibration is None:
        return None, "no fit"
    add_fit(s, record.run_id, FitKind.STATIC, record.calibration)
    if rec is None:
        return None, "recording not readable"
    try:
        diagnosis = diagnose(rec)
    except (RuntimeError, ValueError) as exc:
        note = f"diagnosis not performed: {exc}"
        merge_params(s, record.run_id, {"diagnosis_error": note})
        return None, note
    add_findings(s, record.run_id, diagnosis.get("findings", []))
    merge_params(s, record.run_id, {"diagnosis": diagnosis})
    return diagnosis, ""


def issue_for_run(
    s: Session,
    settings: Settings,
    run_id: str,
    *,
    rec: Recording | None = None,
    diagnosis: dict[str, Any] | None = None,
    diagnosis_note: str = "",
    temp_c: tuple[float, float, float] | None = None,
    now: dt.datetime | None = None,
) -> Certificate:
    """Issue the certificate of a completed run that has a fit.

    :raises LookupError: no such run. :raises ValueError: the run has no fit or is not completed.
    """
    run = s.get(Run, run_id)
    if run is None:
        raise LookupError(f"run {run_id} not found")
    calibration = run.params.get("calibration")
    if run.state.value != "completed" or not isinstance(calibration, dict):
        raise ValueError(f"run {run_id} is {run.state.value} without a fit: no certificate can be issued")
    unit = s.get(Unit, run.unit_id)
    assert unit is not None
    if rec is None and run.recording_path:
        try:
            rec = read_recording(run.recording_path)
        except (OSError, ValueError):
            rec = None
    if diagnosis is None and isinstance(run.params.get("diagnosis"), dict):
        diagnosis = run.params["diagnosis"]
    g_local = rec.sidecar.g_local_m_s2 if rec is not None else None
    inputs = CertificateInputs(
        run={"id": run.id, "procedure": run.procedure, "started_at": run.started_at,
             "finished_at": run.finished_at, "parameters": run.params.get("parameters", {}),
             "bench": run.params.get("bench")},
        unit={"serial": unit.serial, "model": unit.model, "channel_unit": unit.channel_unit},
        calibration=calibration,
        g_local_m_s2=g_local,
        temp_c=temp_c,
        table=_table(rec) if rec is not None else None,
        diagnosis=diagnosis,
        diagnosis_note=diagnosis_note or str(run.params.get("diagnosis_error", "")),
        simulated=bool(run.params.get("sim")),
    )
    now = now or utc_now()
    cert = issue_certificate(s, run_id, {"pending": run_id}, now=now)
    content = certificate_content(inputs, laboratory(settings), number=cert.number, issued_at=now)
    cert.content = content
    cert.sha256 = canonical_sha256(content)
    cert.pdf = render_pdf(content, cert.sha256)
    s.flush()
    return cert


def finish_calibration(s: Session, settings: Settings, record: RunRecord) -> Certificate | None:
    """Fit, diagnosis and certificate of a finished calibration run (``None``: no certificate)."""
    rec = None
    if record.calibration is not None:
        try:
            rec = read_recording(record.start.recording_path)
        except (OSError, ValueError):
            rec = None
    diagnosis, note = store_results(s, record, rec)
    if record.calibration is None or record.outcome is None or record.outcome.value != "PASS":
        return None
    return issue_for_run(
        s, settings, record.run_id, rec=rec, diagnosis=diagnosis, diagnosis_note=note,
        temp_c=_temperature(record),
    )


def findings_of(s: Session, run_id: str) -> list[dict[str, Any]]:
    """Stored findings of a run as dicts."""
    return [
        {"effect": f.effect, "summary": f.summary, "parameters": f.parameters, "sigma": f.sigma,
         "delta_bic": f.delta_bic}
        for f in list_findings(s, run_id)
    ]
