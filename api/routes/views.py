"""Conversion of stored rows (and the runner's live runs) to wire models."""

from __future__ import annotations

import dataclasses
from typing import Any

from api.schemas import (
    AuditEntryOut,
    CertificateOut,
    DriftCheckOut,
    LimitCheckOut,
    RunOut,
    SampleGapOut,
    WindowOut,
)
from bench.diagnosis.stored import StoredDiagnosis
from bench.fitted_model import ContractError
from bench.limits import DECISION_RULES
from db.models import AuditAction, Certificate, DriftCheck, Run, RunAudit, RunWindow
from db.models import run_params as rp
from db.repo.results import RunResults
from db.types import unreadable_reason
from station.runs.live import PHASES, window_means
from station.runs.runner import LiveRun


def _kind(run: Run, live: LiveRun | None) -> str:
    if live is not None:
        return live.kind
    kind = run.kind
    return kind if kind in ("calibration", "drift_check") else "other"


def _phase(run: Run, live: LiveRun | None) -> str | None:
    """A live run's phase (recording, analysing, certificate), the runner's or the stored one."""
    if not run.state.is_live:
        return None
    if live is not None and live.phase != "recording":
        return live.phase
    stored = run.live_progress.get("phase") if isinstance(run.live_progress, dict) else None
    return str(stored) if stored in PHASES else "recording"


def run_out(
    run: Run,
    serial: str,
    live: LiveRun | None = None,
    certificate: str | None = None,
    *,
    results: RunResults,
    with_diagnosis: bool = False,
    windows: list[RunWindow] | None = None,
    audit: list[RunAudit] | None = None,
    certificate_content: dict[str, Any] | None = None,
) -> RunOut:
    """A stored run; a live one shows the runner's fresher progress. A stored value that cannot
    be parsed is shown empty and named in ``unreadable`` (:func:`unreadable_fields`).

    :param results: the run's fit and sample gaps (:func:`db.repo.results.results_of_runs`).
    :param with_diagnosis: include the whole diagnosis object (one run's view, not lists).
    :param windows: the run's stored windows (one run's view), ``None`` in lists.
    :param audit: the run's audit rows (one run's view), ``None`` in lists.
    :param certificate_content: the run's certificate (one run's view): its limit checks' U
        replace the stored ones, so the page and the certificate state one U.
    """
    certificate_u = certificate_check_u(certificate_content)
    cal = results.fit
    diag, stored, note = _diagnosis(run)
    gaps = [SampleGapOut(**dataclasses.asdict(g)) for g in results.gaps]
    progress = run.progress
    if live is not None and run.state.is_live:
        progress = max(progress, live.progress)
    return RunOut(
        phase=_phase(run, live),
        id=run.id,
        unit_serial=serial,
        procedure=run.procedure,
        kind=_kind(run, live),
        state=run.state,
        progress=min(1.0, max(0.0, progress)),
        outcome=run.outcome,
        conformity_note=run.conformity_note or None,
        error=run.error,
        bench=run.params.get(rp.BENCH),
        created_at=_readable(run.created_at),
        started_at=_readable(run.started_at),
        finished_at=_readable(run.finished_at),
        n_samples=run.n_samples,
        last_complete_window=run.last_complete_window,
        calibration=cal if isinstance(cal, dict) and unreadable_reason(cal) is None else None,
        certificate_number=certificate,
        n_findings=len(stored.findings) if stored is not None else None,
        diagnosis=diag if with_diagnosis else None,
        diagnosis_note=str(note) if diag is None and note else None,
        n_samples_lost=sum(g.n_lost or 0 for g in gaps) if run.n_samples is not None or gaps else None,
        gaps=gaps if with_diagnosis else None,
        certificate_note=run.certificate_error or None,
        limit_checks=[_check(c, certificate_u) for c in (run.limit_checks or [])],
        decision_rule=_rule(run.limit_checks),
        windows=[_window(w) for w in windows] if windows is not None else None,
        unreadable=unreadable_fields(run, cal),
        started_by=started_by(audit) if audit is not None else None,
        audit=[audit_out(a) for a in audit] if audit is not None else None,
    )


_RUN_FIELDS = (
    "params",
    "diagnosis",
    "created_at",
    "started_at",
    "finished_at",
    "limit_checks",
    "live_progress",
    "final_event",
)


def unreadable_fields(run: Run, fit: dict[str, Any] | None = None) -> str | None:
    """``"params: not JSON: ... ; created_at: not a time: ..."`` for the run's stored values (and
    its fit's ``calibrate --json`` object, ``fit``) that cannot be parsed, ``None`` when every one
    reads."""
    found = [f"{name}: {why}" for name in _RUN_FIELDS if (why := unreadable_reason(getattr(run, name)))]
    if (why := unreadable_reason(fit)) is not None:
        found.append(f"fit: {why}")
    return "; ".join(found) or None


def _readable(value: Any) -> Any:
    return None if unreadable_reason(value) is not None else value


def audit_out(row: RunAudit) -> AuditEntryOut:
    """One audit row on the wire."""
    return AuditEntryOut(
        at=row.at,
        actor=row.actor,
        action=row.action.value,
        state=row.state,
        detail=row.detail,
        window_index=row.window_index,
    )


def started_by(audit: list[RunAudit]) -> str | None:
    """Who asked for the run: the actor of its first start request."""
    return next((a.actor for a in audit if a.action is AuditAction.START), None)


def _diagnosis(run: Run) -> tuple[dict[str, Any] | None, StoredDiagnosis | None, object]:
    """The run's stored diagnosis as stored and parsed, and why there is none: a stored
    diagnosis that cannot be parsed is shown as none, with the parser's message naming the key."""
    diag = run.diagnosis
    if diag is None:
        return None, None, run.diagnosis_error
    try:
        stored = StoredDiagnosis.from_contract(diag, f"run {run.id}: stored diagnosis")
    except ContractError as exc:
        return None, None, str(exc)
    return diag, stored, None


def certificate_check_u(content: dict[str, Any] | None) -> dict[str, Any]:
    """The U of each limit check a certificate states, by quantity name (empty: none)."""
    conformity = content.get("conformity") if isinstance(content, dict) else None
    rows = conformity.get("checks") if isinstance(conformity, dict) else None
    return {
        str(r["quantity"]): r.get("expanded_uncertainty")
        for r in rows or []
        if isinstance(r, dict) and "quantity" in r
    }


def _check(c: dict[str, Any], certificate_u: dict[str, Any] | None = None) -> LimitCheckOut:
    """A stored check; one stored before checks carried U has its tolerance as acceptance
    interval. With a certificate, U is the certificate's (its budget), the one U the run states."""
    out = dict(c)
    if certificate_u and isinstance(certificate_u.get(str(c.get("name"))), int | float):
        out["expanded_uncertainty"] = certificate_u[str(c.get("name"))]
    if "acceptance_low" not in out:
        out["acceptance_low"], out["acceptance_high"] = out.get("low"), out.get("high")
    return LimitCheckOut(**{k: v for k, v in out.items() if k in LimitCheckOut.model_fields})


def _rule(checks: list[Any] | None) -> str | None:
    if not checks:
        return None
    rule = str(checks[0].get("rule", "simple-acceptance"))
    return DECISION_RULES.get(rule, rule)


def _window(w: RunWindow) -> WindowOut:
    return WindowOut(
        index=w.index,
        label=w.label,
        kind=w.kind,
        start_s=w.start_s,
        end_s=w.end_s,
        n_samples=w.n_samples,
        pose_deg=[float(a) for a in (w.pose_deg or [])],
        means=window_means(w.means),
    )


def live_out(live: LiveRun, bench: str) -> RunOut:
    """A run the runner holds that has no database row (yet, or ever: it failed before)."""
    return RunOut(
        id=live.id,
        unit_serial=live.unit_serial,
        procedure=live.procedure,
        kind=live.kind,
        state=live.state,
        progress=min(1.0, max(0.0, live.progress)),
        error=live.error,
        bench=bench,
        created_at=live.created_at,
    )


def conformity_withdrawn(cert: Certificate, run: Run | None) -> str | None:
    """Why the statement of conformity an issued certificate makes no longer stands: the run's
    ``conformity_note`` when the certificate states PASS or FAIL and the run holds no verdict now
    (withdrawn, e.g. by migration 0006); ``None`` otherwise. The document stays as issued."""
    conformity = cert.content.get("conformity") if isinstance(cert.content, dict) else None
    stated = isinstance(conformity, dict) and conformity.get("requested") is True
    if run is None or not stated or run.outcome in ("PASS", "FAIL"):
        return None
    return run.conformity_note or "the run no longer holds the verdict this certificate states"


def certificate_out(cert: Certificate, serial: str, run: Run | None = None) -> CertificateOut:
    """An issued certificate (with :func:`conformity_withdrawn` of ``run``, its run)."""
    return CertificateOut(
        number=cert.number,
        run_id=cert.run_id,
        unit_serial=serial,
        issued_at=cert.issued_at,
        sha256=cert.sha256,
        content=cert.content,
        conformity_withdrawn=conformity_withdrawn(cert, run),
    )


def drift_out(check: DriftCheck, serial: str, reference: str | None) -> DriftCheckOut:
    """A stored drift check."""
    result: dict[str, Any] = dict(check.result)
    return DriftCheckOut(
        id=check.id,
        unit_serial=serial,
        checked_at=check.checked_at,
        flagged=check.flagged,
        run_id=check.run_id,
        reference_certificate=reference,
        result=result,
    )
