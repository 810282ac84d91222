"""The audit trail of runs: one row per action, written in the transaction of the action."""

from __future__ import annotations

import datetime as dt
import getpass
import socket

import sqlalchemy as sa
from sqlalchemy.orm import Session

from bench.run_state import RunState
from db.models import AuditAction, RunAudit
from db.types import utc_now


def record_action(
    session: Session,
    run_id: str,
    action: AuditAction,
    actor: str,
    *,
    state: RunState | None = None,
    detail: str = "",
    window_index: int | None = None,
    at: dt.datetime | None = None,
) -> RunAudit:
    """Add one audit row for ``run_id`` (flushed with the caller's transaction).

    :raises ValueError: an empty actor (every action names who took it), or a ``state`` action
        without its state.
    """
    if not actor.strip():
        raise ValueError(f"run {run_id}: an audit row needs an actor (operator name, agent or system)")
    if (action is AuditAction.STATE) != (state is not None):
        raise ValueError(f"run {run_id}: a state row carries the new state, a request none ({action.value})")
    row = RunAudit(
        run_id=run_id,
        at=at or utc_now(),
        actor=actor[:200],
        action=action,
        state=state,
        detail=detail,
        window_index=window_index,
    )
    session.add(row)
    session.flush()
    return row


def record_resume(
    session: Session, run_id: str, actor: str, next_window_index: int, at: dt.datetime | None = None
) -> RunAudit:
    """The audit row of a resume asked by ``actor``: the run picks up at ``next_window_index``
    (a queued resume and a resume claimed at once write the same row)."""
    return record_action(
        session,
        run_id,
        AuditAction.RESUME,
        actor,
        detail=f"from window {next_window_index}",
        window_index=next_window_index,
        at=at,
    )


def record_state(
    session: Session,
    run_id: str,
    state: RunState,
    actor: str,
    detail: str = "",
    *,
    window_index: int | None = None,
    at: dt.datetime | None = None,
) -> RunAudit:
    """Add the audit row of a state change."""
    return record_action(
        session,
        run_id,
        AuditAction.STATE,
        actor,
        state=state,
        detail=detail,
        window_index=window_index,
        at=at,
    )


def run_audit(session: Session, run_id: str) -> list[RunAudit]:
    """The run's audit rows, in the order they were written."""
    return list(session.scalars(sa.select(RunAudit).where(RunAudit.run_id == run_id).order_by(RunAudit.id)))


def command_line_actor() -> str:
    """Who acts from the command line of this machine: ``"USER (command line on HOST)"``."""
    try:
        user = getpass.getuser()
    except (KeyError, OSError):  # no user name for the uid (a container)
        user = "unknown user"
    return f"{user} (command line on {socket.gethostname()})"
