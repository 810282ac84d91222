"""Runs whose process died: marking them ``interrupted`` and resuming them.

A run in a live state (``queued``, ``running``, ``paused``, ``suspended``) needs a live
owner. :func:`mark_interrupted_runs` turns it ``interrupted`` when its owner is gone: on
this host, the owner pid no longer exists; on any host, the last heartbeat is older than
``stale_after_s``. :func:`resume_point` says where to pick up (the window after the last
complete one, and where to cut the recording file), :func:`claim_for_resume` hands the
run to a new owner, exactly once.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass

import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import (
    ACTIVE_STATES,
    AGENT,
    RESUMABLE_STATES,
    SYSTEM,
    Run,
    RunState,
    RunWindow,
    SampleChunk,
)
from db.notify import notify_run
from db.process import process_alive
from db.repo.audit import record_resume, record_state
from db.types import utc_now

DEFAULT_STALE_AFTER_S = 300.0


def mark_interrupted_runs(
    session: Session,
    host: str,
    is_alive: Callable[[int], bool] = process_alive,
    *,
    stale_after_s: float = DEFAULT_STALE_AFTER_S,
    now: dt.datetime | None = None,
) -> list[str]:
    """Mark active runs with a dead owner ``interrupted``; return their ids. A run queued for
    an agent (``queued``, no owner yet) is waiting, not dead, however long it waits.

    :param host: this machine's host name; only its pids are checked with ``is_alive``.
    :param is_alive: ``pid -> bool`` for processes on ``host``.
    :param stale_after_s: a heartbeat older than this (s) means the owner is gone, on any host.
    """
    now = now or utc_now()
    cutoff = now - dt.timedelta(seconds=stale_after_s)
    candidates = session.execute(
        sa.select(Run.id, Run.owner_pid, Run.owner_host, Run.heartbeat_at, Run.created_at).where(
            Run.state.in_(list(ACTIVE_STATES)),
            # a queued run with no owner waits for its bench's agent (db.repo.queue): not dead
            sa.not_(sa.and_(Run.state == RunState.QUEUED, Run.owner_pid.is_(None))),
        )
    ).all()
    dead: list[tuple[str, str]] = []
    for run_id, pid, owner_host, heartbeat_at, created_at in candidates:
        last_seen = heartbeat_at or created_at
        if owner_host == host and pid is not None and not is_alive(pid):
            dead.append((run_id, f"owner process {pid} on {host} is gone"))
        elif last_seen is not None and last_seen < cutoff:
            dead.append((run_id, f"no heartbeat since {last_seen.isoformat()} (owner {pid}@{owner_host})"))
    marked: list[str] = []
    for run_id, reason in dead:
        result = session.execute(
            sa.update(Run)
            .where(Run.id == run_id, Run.state.in_(list(ACTIVE_STATES)))
            .values(state=RunState.INTERRUPTED, error=f"interrupted: {reason}")
            .execution_options(synchronize_session="fetch")
        )
        if getattr(result, "rowcount", 0) == 1:
            record_state(
                session,
                run_id,
                RunState.INTERRUPTED,
                SYSTEM,
                reason,
                window_index=_next_window(session, run_id),
                at=now,
            )
            marked.append(run_id)
    return marked


@dataclass(frozen=True)
class ResumePoint:
    """Where an interrupted run picks up.

    :param next_window_index: the first window to record again (0 if none completed).
    :param keep_until_s: recording time (s) up to which data are kept (end of the last
        complete window), ``None`` if no window completed.
    :param keep_chunks: number of chunks kept (chunk seqs ``0 .. keep_chunks-1``).
    :param keep_samples: samples kept in the recording.
    :param keep_end_byte: cut the recording CSV to this size (bytes) before appending;
        ``None``: no chunk is kept, start the file again.
    """

    run_id: str
    recording_path: str | None
    next_window_index: int
    keep_until_s: float | None
    keep_chunks: int
    keep_samples: int
    keep_end_byte: int | None


def resume_point(session: Session, run_id: str) -> ResumePoint:
    """Where ``run_id`` resumes: after its last complete window, on a chunk boundary.

    The kept chunks are those up to the first chunk whose last sample reaches the end of
    the last complete window; later chunks hold a window that did not complete.

    :raises LookupError: no such run.
    """
    run = session.get(Run, run_id)
    if run is None:
        raise LookupError(f"run {run_id} not found")
    chunks = list(
        session.scalars(sa.select(SampleChunk).where(SampleChunk.run_id == run_id).order_by(SampleChunk.seq))
    )
    last_window = None
    if run.last_complete_window is not None:
        last_window = session.scalars(
            sa.select(RunWindow).where(
                RunWindow.run_id == run_id, RunWindow.index == run.last_complete_window
            )
        ).one_or_none()
    if last_window is None:
        return ResumePoint(run_id, run.recording_path, 0, None, 0, 0, None)
    if any(c.end_byte is None for c in chunks):
        missing = [c.seq for c in chunks if c.end_byte is None]
        raise ValueError(
            f"run {run_id}: chunks {missing} have no byte offset; the recording cannot be cut safely"
        )
    kept = 0
    for chunk in chunks:
        kept += 1
        if chunk.last_t_s >= last_window.end_s:
            break
    if kept == 0 or chunks[kept - 1].last_t_s < last_window.end_s:
        raise ValueError(
            f"run {run_id}: window {last_window.index} ends at {last_window.end_s} s but the durable chunks "
            f"end at {chunks[-1].last_t_s if chunks else 'nothing'}: the recording does not hold the window"
        )
    last = chunks[kept - 1]
    return ResumePoint(
        run_id,
        run.recording_path,
        last_window.index + 1,
        last_window.end_s,
        kept,
        last.first_sample + last.n_samples,
        last.end_byte,
    )


def claim_for_resume(
    session: Session,
    run_id: str,
    *,
    owner_pid: int,
    owner_host: str,
    actor: str = SYSTEM,
    now: dt.datetime | None = None,
) -> ResumePoint:
    """Give an ``interrupted`` run to a new owner and return its resume point; ``actor`` (who
    asked) is stored in the run's audit trail.

    Chunks past the resume point are deleted (the caller cuts the file to
    ``keep_end_byte``). Exactly one of several concurrent claimers succeeds.

    :raises LookupError: no such run. :raises ValueError: the run is not resumable.
    """
    point = resume_point(session, run_id)
    now = now or utc_now()
    result = session.execute(
        sa.update(Run)
        .where(Run.id == run_id, Run.state.in_(list(RESUMABLE_STATES)))
        .values(
            state=RunState.RUNNING,
            owner_pid=owner_pid,
            owner_host=owner_host,
            heartbeat_at=now,
            error=None,
            resume_count=Run.resume_count + 1,
        )
        .execution_options(synchronize_session="fetch")
    )
    if getattr(result, "rowcount", 0) != 1:
        state = session.scalar(sa.select(Run.state).where(Run.id == run_id))
        raise ValueError(
            f"run {run_id} is {state.value if state else 'gone'}; only "
            f"{sorted(s.value for s in RESUMABLE_STATES)} runs can be resumed"
        )
    session.execute(
        sa.delete(SampleChunk).where(SampleChunk.run_id == run_id, SampleChunk.seq >= point.keep_chunks)
    )
    record_resume(session, run_id, actor, point.next_window_index, at=now)
    return point


def mark_run_interrupted(
    session: Session, run_id: str, reason: str, *, actor: str = AGENT, now: dt.datetime | None = None
) -> bool:
    """A live run stops without finishing (its process is going away): ``interrupted``, resumable
    (an audit row by ``actor``, the run's owner by default)."""
    now = now or utc_now()
    result = session.execute(
        sa.update(Run)
        .where(Run.id == run_id, Run.state.in_(list(ACTIVE_STATES)))
        .values(state=RunState.INTERRUPTED, error=f"interrupted: {reason}", heartbeat_at=now)
        .execution_options(synchronize_session="fetch")
    )
    changed = bool(getattr(result, "rowcount", 0) == 1)
    if changed:
        record_state(
            session,
            run_id,
            RunState.INTERRUPTED,
            actor,
            reason,
            window_index=_next_window(session, run_id),
            at=now,
        )
        notify_run(session, run_id)
    return changed


def _next_window(session: Session, run_id: str) -> int:
    """The window a run was recording (or about to record): the one after its last complete one."""
    last = session.scalar(sa.select(Run.last_complete_window).where(Run.id == run_id))
    return 0 if last is None else last + 1


def rewind_run(session: Session, run_id: str, next_window_index: int) -> None:
    """Forget windows ``>= next_window_index`` (they will be recorded again) and set
    ``last_complete_window`` to ``next_window_index - 1`` (``None`` for 0)."""
    if next_window_index < 0:
        raise ValueError(f"run {run_id}: next window index {next_window_index} < 0")
    session.execute(
        sa.delete(RunWindow).where(RunWindow.run_id == run_id, RunWindow.index >= next_window_index)
    )
    session.execute(
        sa.update(Run)
        .where(Run.id == run_id)
        .values(last_complete_window=next_window_index - 1 if next_window_index > 0 else None)
        .execution_options(synchronize_session="fetch")
    )


def drop_chunks_from(session: Session, run_id: str, seq: int) -> int:
    """Delete the run's chunk rows with ``seq`` or later (a resumed writer numbers from ``seq``)."""
    result = session.execute(
        sa.delete(SampleChunk).where(SampleChunk.run_id == run_id, SampleChunk.seq >= seq)
    )
    return int(getattr(result, "rowcount", 0) or 0)
