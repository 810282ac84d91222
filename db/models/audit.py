"""The audit trail of a run: every action on it, who took it and when (UTC).

An operator's request (start, pause, continue, abort, resume) is stored with the operator's
name (the name stored with the API token that asked); what the bench's agent or the service
did on its own (a state change: the pause applied, a suspension by the interlock or the
temperature, the run going on again, an interruption by a crash, the final state) is stored
with :data:`AGENT` or :data:`SYSTEM`. The rows are kept with the run (deleted with it) and
never updated.
"""

from __future__ import annotations

import datetime as dt
import enum

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column

from bench.run_state import RunState
from db.base import Base, IntId
from db.models._enum import value_enum

AGENT = "agent"
"""Actor of what the bench's agent did on its own (the sequencer's state changes)."""
SYSTEM = "system"
"""Actor of what the service did on its own (a run marked interrupted after a crash, the
nightly drift scheduler)."""


class AuditAction(enum.Enum):
    """What was done to a run: an operator's request, a state change (with the new state), or
    ``withdraw``: a stored statement of conformity (PASS or FAIL) withdrawn from the record, the
    detail starting with the withdrawn outcome and saying why (migration 0006)."""

    START = "start"
    PAUSE = "pause"
    CONTINUE = "continue"
    ABORT = "abort"
    RESUME = "resume"
    STATE = "state"
    WITHDRAW = "withdraw"


class RunAudit(IntId, Base):
    """One action on a run.

    :param at: when (UTC): the request's arrival, or the state change on the owner's clock.
    :param actor: the operator's name, :data:`AGENT` or :data:`SYSTEM`.
    :param action: :class:`AuditAction`.
    :param state: the run's state after a ``state`` action (``None`` for a request).
    :param detail: the reason or request text, e.g. ``"interlock open"``, ``"resumed from window 5"``.
    :param window_index: the window the action concerns: the window being recorded at a
        state change, the first window recorded again by a resume; ``None`` when none.
    """

    __tablename__ = "run_audit"

    run_id: Mapped[str] = mapped_column(
        sa.String(64), sa.ForeignKey("run.id", ondelete="CASCADE"), index=True
    )
    at: Mapped[dt.datetime]
    actor: Mapped[str] = mapped_column(sa.String(200))
    action: Mapped[AuditAction] = mapped_column(value_enum(AuditAction, "audit_action"))
    state: Mapped[RunState | None] = mapped_column(value_enum(RunState, "audit_state"))
    detail: Mapped[str] = mapped_column(sa.Text, default="")
    window_index: Mapped[int | None]
