"""The end of a bench run: fit the recording, judge it against the unit's limits, and tell the
run's observers, retrying one that cannot store it yet.

:func:`execute` runs a prepared sequencer to its end and gives the :class:`~bench.records.RunRecord`
(outcome PASS or FAIL from the limits, ERROR when the fit or the check fails, or the
acquisition's own outcome); :func:`finish_observers` hands it to every observer.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from api.certificates.conformity import check_uncertainties
from api.certificates.issue import limits_model_name, run_budget
from api.settings import Settings
from bench.calibration import CalibrationResult, calibrate_recording
from bench.estimation.scalar_fit import PARAMETER_NAMES as SCALAR_NAMES
from bench.estimation.static_design import PARAMETER_NAMES as STATIC_NAMES
from bench.fitted_model import FittedModel
from bench.limit_check import LimitCheck
from bench.limits import UnitLimits, describe, load_limits, verdict
from bench.recording import Recording
from bench.recording.reader import read_recording
from bench.records import Outcome, RunRecord, RunState
from bench.run_observer import RunObserver
from bench.sequencer.loop import Sequencer


def fit_covariance(result: CalibrationResult) -> tuple[tuple[tuple[float, ...], ...], tuple[str, ...]]:
    """The fit's parameter covariance and the names of its rows (static, scalar or dynamic fit)."""
    dynamic = getattr(result, "fit", None)
    if dynamic is not None:
        names = tuple(dynamic.names)
    else:
        names = SCALAR_NAMES if result.method == "scalar" else STATIC_NAMES
    cov = tuple(tuple(float(v) for v in row) for row in np.asarray(result.cov, dtype=float))
    if len(cov) != len(names):
        raise ValueError(f"fit covariance is {len(cov)}x{len(cov)} for {len(names)} parameter names")
    return cov, names


def judged_uncertainties(
    rec: Recording, calibration: FittedModel, settings: Settings | None, g_check_n: int | None = None
) -> dict[str, float]:
    """The expanded uncertainty of each value the limits check: with ``settings``, as the
    certificate will state it (the uncertainty budget with the bench's Type B settings, needed
    by a guard band); without, or when no budget can be formed, the fit's Type A σ with k = 2
    (simple acceptance, where U is stated beside the verdict; the certificate states its own)."""
    budget = None
    if settings is not None:
        budget, _why = run_budget(rec, calibration, settings)
    return check_uncertainties(calibration, budget, g_check_n)


def run_record(
    seq: Sequencer,
    acq_outcome: Outcome | None,
    error: str | None,
    csv_path: Path,
    limits: UnitLimits | None,
    settings: Settings | None = None,
) -> RunRecord:
    calibration: CalibrationResult | None = None
    outcome = acq_outcome
    checks: tuple[LimitCheck, ...] = ()
    cov: tuple[tuple[float, ...], ...] | None = None
    names: tuple[str, ...] = ()
    rec: Recording | None = None
    if outcome is None:
        try:
            rec = read_recording(csv_path)
            calibration = calibrate_recording(rec)
            cov, names = fit_covariance(calibration)
        except ValueError as exc:
            outcome, error = Outcome.ERROR, f"fit failed: {exc}"
    if calibration is not None and rec is not None:
        try:
            n_g = int(np.size(calibration.g_after.error_m_s2))
            fitted = calibration.fitted_model()
            # the budget (refits for a moving table) only where the decision needs it: a guard band
            guarded = limits is not None and limits.decision_rule == "guarded-acceptance"
            us = judged_uncertainties(rec, fitted, settings if guarded else None, n_g) if limits else None
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
        calibration=calibration,
        limit_checks=checks,
        n_samples=seq.recorder.n_rows,
        dwell=seq.dwell,
        fit_covariance=cov,
        fit_param_names=names,
        gaps=tuple(seq.recorder.gaps),
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
    limits: UnitLimits | None,
    settings: Settings | None = None,
) -> RunRecord:
    acq = seq.run()
    record = run_record(seq, acq.outcome, acq.error, csv_path, limits, settings)
    finish_observers(observers, record)
    return record


def limits_for(settings: Settings, model: str | None, channel_unit: str) -> UnitLimits | None:
    """The limits that judge a unit: its registered ``model`` if the limits file has it, else
    ``settings.limits_model``; ``None`` when neither applies to ``channel_unit`` outputs.

    :raises ValueError: the limits file is unreadable or malformed (named).
    """
    table = load_limits(settings.limits_file)
    name = limits_model_name(settings, model)
    chosen = table.get(name) if name else None
    return chosen if chosen is not None and chosen.channel_unit == channel_unit else None
