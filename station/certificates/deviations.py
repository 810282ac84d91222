"""What a certificate says about the run's course: every deviation from the procedure (ISO/IEC
17025:2017 7.8.2.1 n) and who acted on the run, from the run's audit trail and its sample gaps.

A procedure runs its steps without a break. A deviation is anything else the stored run shows:

* a hold, from the state change to ``paused`` (an operator's request) or ``suspended`` (the
  interlock, the temperature band: automatic) to the next state change, with its duration on
  the wall clock, the window it came at and who asked; the interrupted step was executed again,
  so no sample of the hold is in a window;
* an interruption (the owner process died or the service shut down) and the resume that
  continued the run from window k, with who asked;
* every sample gap, where it was and what was done (``bench.records.GapRecord``).

A run with none of these says so in words that name what was checked, never a bare "none".
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy.orm import Session

from bench.run_state import RunState
from db.repo.audit import run_audit
from station.certificates.inputs import ActionFact, RunFacts

HELD = frozenset({RunState.PAUSED, RunState.SUSPENDED})


def utc_text(at: dt.datetime) -> str:
    """``2026-11-20 02:00:01 UTC``."""
    return f"{at.astimezone(dt.UTC):%Y-%m-%d %H:%M:%S} UTC"


def _window(index: int | None) -> str:
    return f"at window {index}" if index is not None else "between windows"


def _hold(start: ActionFact, end: ActionFact | None, asked: ActionFact | None) -> str:
    until = (
        f"for {(end.at - start.at).total_seconds():.0f} s"
        if end is not None
        else "until the run ended (not continued)"
    )
    if start.state is RunState.PAUSED:
        who = (
            f"asked by {asked.actor} at {utc_text(asked.at)}" if asked is not None else "asked by an operator"
        )
        what = (
            f"paused by the operator {until} from {utc_text(start.at)} {_window(start.window_index)} ({who})"
        )
    else:
        reason = f": {start.detail}" if start.detail else ""
        what = (
            f"suspended automatically {until} from {utc_text(start.at)} {_window(start.window_index)}{reason}"
        )
    return what + "; the interrupted step was executed again, no sample of the hold is in a window"


def _gap(g: dict[str, Any]) -> str:
    n = g.get("n_lost")
    lost = f"{n} samples" if isinstance(n, int) else "an unknown number of samples"
    t = g.get("t_last_s")
    when = (
        f"after {t:.3f} s of the recording" if isinstance(t, int | float) else "at the start of the recording"
    )
    label = f" ({g['window_label']})" if g.get("window_label") else ""
    where = (
        f"in window {g['window_index']}{label}" if g.get("window_index") is not None else "between windows"
    )
    action = g.get("action") or "recorded where it happened"
    return f"{lost} lost ({g.get('cause', 'unknown')}) {when}, {where}: {action}"


def run_deviations(run: RunFacts) -> list[str]:
    """Every deviation from the procedure the stored run shows, in the order they happened."""
    out: list[str] = []
    held: ActionFact | None = None
    asked: dict[str, ActionFact] = {}
    for a in run.actions:
        if a.action == "withdraw":
            continue
        if a.action != "state":
            asked[a.action] = a
            if a.action == "resume":
                out.append(
                    f"resumed {_window(a.window_index)} on request of {a.actor} at {utc_text(a.at)}: the "
                    "windows before it were kept, the recording after the last complete window was cut "
                    "and recorded again"
                )
            continue
        if held is not None and a.state != held.state:
            out.append(_hold(held, a, asked.get("pause")))
            held = None
        if a.state in HELD and held is None:
            held = a
        elif a.state is RunState.INTERRUPTED:
            reason = f": {a.detail}" if a.detail else ""
            out.append(f"interrupted at {utc_text(a.at)} {_window(a.window_index)}{reason}")
    if held is not None:
        out.append(_hold(held, None, asked.get("pause")))
    out += [_gap(g) for g in run.sample_gaps if isinstance(g, dict)]
    return out


def no_deviation(run: RunFacts) -> str:
    """What the certificate says when :func:`run_deviations` found nothing."""
    if not run.actions:
        return "not recorded: this run has no stored record of its course (made before runs kept one)"
    return "none: the run was neither paused, suspended nor interrupted, and no sample was lost"


def started_by(run: RunFacts) -> str:
    """Who asked for the run (its first start request), or why that is not known."""
    first = next((a for a in run.actions if a.action == "start"), None)
    if first is None:
        return "not recorded (the run was made before runs kept their audit trail)"
    return f"{first.actor} at {utc_text(first.at)}"


def action_lines(run: RunFacts) -> list[str]:
    """The run's audit trail, one line per action: time, who, what."""
    lines = []
    for a in run.actions:
        if a.state is not None:
            what = f"state {a.state.value}"
        else:
            what = "statement of conformity withdrawn" if a.action == "withdraw" else f"{a.action} requested"
        detail = f" ({a.detail})" if a.detail else ""
        lines.append(f"{utc_text(a.at)}  {a.actor}: {what}{detail}")
    return lines


def run_record_section(run: RunFacts) -> dict[str, Any]:
    """The certificate's ``run_record``: who started the run and every action on it."""
    return {"started_by": started_by(run), "actions": action_lines(run)}


def stored_actions(session: Session, run_id: str) -> tuple[ActionFact, ...]:
    """The run's audit trail as the certificate states it (``db.models.RunAudit`` rows)."""
    return tuple(
        ActionFact(
            at=a.at,
            actor=a.actor,
            action=a.action.value,
            state=a.state,
            detail=a.detail,
            window_index=a.window_index,
        )
        for a in run_audit(session, run_id)
    )
