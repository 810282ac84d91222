"""The end of a bench run: analyse the recording (read once, fitted once:
``bench.calibration.analysis.analyse``), judge the fit against the unit's limits, and tell the
run's observers, retrying one that cannot store it yet.

:func:`execute` runs a prepared sequencer to its end and gives the :class:`~bench.records.RunRecord`
(outcome PASS or FAIL from the limits, none with a note saying why when no limits apply,
ERROR when the fit or the check fails, or the acquisition's own outcome) with its
:class:`~bench.calibration.analysis.Analysis`, which the service's finish passes on;
:func:`finish_observers` hands it to every observer.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

from bench.calibration.analysis import Analysis, analyse
from bench.fitted_model import FittedModel
from bench.limit_check import LimitCheck
from bench.limits import LimitsChoice, describe, verdict
from bench.recording.reader import read_recording
from bench.records import RunRecord
from bench.run_observer import RunObserver, announce_phase
from bench.run_state import Outcome, RunState
from bench.sequencer.loop import Sequencer
from station.certificates.budget import TypeBSettings, analysis_budget
from station.certificates.conformity import check_uncertainties, limits_choice
from station.settings import Settings


def judged_uncertainties(
    analysis: Analysis, calibration: FittedModel, settings: Settings | None
) -> dict[str, float]:
    """The expanded uncertainty of each value the limits check: with ``settings``, as the
    certificate will state it (the uncertainty budget with the bench's Type B settings, needed
    by a guard band); without, or when no budget can be formed, the fit's Type A σ with k = 2
    (simple acceptance, where U is stated beside the verdict; the certificate states its own)."""
    budget = None
    if settings is not None:
        budget, _why = analysis_budget(analysis, calibration, TypeBSettings.of(settings))
    return check_uncertainties(calibration, budget, analysis.fit.g_after.error_m_s2.size)


def run_record(
    seq: Sequencer,
    acq_outcome: Outcome | None,
    error: str | None,
    csv_path: Path,
    choice: LimitsChoice,
    settings: Settings | None = None,
) -> RunRecord:
    """The run's record from the acquisition's end: the fit and the verdict of ``choice``'s
    limits when every step was done (``acq_outcome`` ``None``), else the acquisition's own end."""
    limits = choice.limits
    analysis: Analysis | None = None
    outcome = acq_outcome
    checks: tuple[LimitCheck, ...] = ()
    cov: tuple[tuple[float, ...], ...] | None = None
    names: tuple[str, ...] = ()
    if outcome is None:
        try:
            analysis = analyse(read_recording(csv_path))
            cov, names = analysis.fit.covariance_rows()
        except ValueError as exc:
            outcome, error = Outcome.ERROR, f"fit failed: {exc}"
    if analysis is not None:
        try:
            fitted = analysis.fitted_model()
            # the budget (refits for a moving table) only where the decision needs it: a guard band
            guarded = limits is not None and limits.decision_rule == "guarded-acceptance"
            us = judged_uncertainties(analysis, fitted, settings if guarded else None) if limits else None
            outcome, checks = verdict(fitted, limits, us)
        except ValueError as exc:
            outcome, error = Outcome.ERROR, f"limits check failed: {exc}"
        if outcome is Outcome.FAIL:
            error = "outside limits: " + "; ".join(describe(c) for c in checks if not c.passed)
    return RunRecord(
        start=seq.start,
        state=RunState.finished(outcome),
        outcome=outcome,
        windows=tuple(seq.recorder.windows),
        error=error,
        calibration=analysis.fit if analysis is not None else None,
        limit_checks=checks,
        conformity_note=choice.note if outcome is None else "",
        n_samples=seq.recorder.n_rows,
        dwell=seq.dwell,
        fit_covariance=cov,
        fit_param_names=names,
        gaps=tuple(seq.recorder.gaps),
        analysis=analysis,
    )


class RunNotStored(RuntimeError):
    """A run ended but an observer (the database) could not store its end; names both."""


def finish_observers(
    observers: Sequence[RunObserver], record: RunRecord, retry_s: float = 30.0, wait_s: float = 0.5
) -> None:
    """Tell every observer the run ended; a failing one (a database write refused: disk full,
    connection lost) is retried with growing waits for ``retry_s``, so a transient failure
    still stores the outcome instead of leaving the run ``running``.

    :raises RunNotStored: an observer still failed at the end (each one named).
    """
    problems = []
    for obs in observers:
        deadline = time.monotonic() + retry_s
        pause = wait_s
        while True:
            try:
                obs.on_finish(record)
                break
            except Exception as exc:  # any observer failure: retried, then reported
                if time.monotonic() + pause > deadline:
                    problems.append(f"{type(obs).__name__}: {type(exc).__name__}: {exc}")
                    break
                time.sleep(pause)
                pause = min(2 * pause, 5.0)
    if problems:
        outcome = record.outcome.value if record.outcome else record.state.value
        raise RunNotStored(
            f"run {record.run_id} ended {outcome} but its end could not be stored "
            f"(retried {retry_s:g} s): " + "; ".join(problems)
        )


def execute(
    seq: Sequencer,
    csv_path: Path,
    observers: Sequence[RunObserver],
    limits: LimitsChoice,
    settings: Settings | None = None,
) -> RunRecord:
    acq = seq.run()
    if acq.outcome is None:  # every step done: the fit and the verdict follow
        announce_phase(observers, seq.start.run_id, "analysing")
    record = run_record(seq, acq.outcome, acq.error, csv_path, limits, settings)
    finish_observers(observers, record)
    return record


def limits_for(settings: Settings, model: str | None, channel_unit: str) -> LimitsChoice:
    """The limits that judge a unit registered as ``model`` with ``channel_unit`` outputs, or
    why none do (:func:`station.certificates.conformity.limits_choice`).

    :raises ValueError: the limits file is unreadable or malformed (named).
    """
    return limits_choice(settings, model, channel_unit)
