"""Runs: start (operator), list, read, abort, pause, resume (operator), and the live event stream."""

from __future__ import annotations

from collections.abc import AsyncIterator
from typing import Annotated, Any

import anyio.to_thread
import sqlalchemy as sa
from fastapi import APIRouter, HTTPException, Query, Request, status
from fastapi.responses import StreamingResponse
from starlette.concurrency import run_in_threadpool

from api.deps import (
    OperatorPrincipalDep,
    RunnerDep,
    ServicesDep,
    SessionDep,
    SettingsDep,
    ViewerDep,
    ViewerLinkDep,
)
from api.routes.views import audit_out, live_out, run_out
from api.runs.events import RunSnapshot, SnapshotCache
from api.runs.stream import run_events
from api.schemas import (
    MAX_PAGE_OFFSET,
    AbortOut,
    AuditEntryOut,
    RunActionOut,
    RunCreate,
    RunCreated,
    RunOut,
    RunStateName,
)
from db.models import Certificate, RunState
from db.repo.audit import run_audit
from db.repo.progress import list_windows
from db.repo.queue import finishing_since
from db.repo.results import results_of_runs
from db.repo.runs import get_run, list_runs
from station.certificates.conformity import unit_warnings
from station.execution.resume_admission import ResumeRefused
from station.runs.queue import NotResumable

router = APIRouter(prefix="/api/runs", tags=["runs"])


@router.post(
    "",
    status_code=status.HTTP_202_ACCEPTED,
    response_model=RunCreated,
    responses={
        422: {"description": "a bad procedure, dwell or serial; an unknown bench or one that cannot run it"}
    },
)
def start_run(
    body: RunCreate, runner: RunnerDep, session: SessionDep, settings: SettingsDep, who: OperatorPrincipalDep
) -> RunCreated:
    """Queue a procedure for a unit on the bench ``bench`` names, or (without it) on a free bench
    whose agent can run the procedure: the bench's agent starts it as soon as the bench is free
    (at once when idle; after the runs queued before it when busy). ``warnings`` says, e.g.,
    that the unit's model has no limits, so its certificate will make no statement of conformity."""
    try:
        live = runner.start(
            body.unit_serial,
            body.procedure,
            dwell_s=body.dwell_s,
            bench=body.bench,
            parameters=body.parameters,
            actor=who.actor,
        )
    except ValueError as exc:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(exc)) from None
    with session.begin():
        warnings = unit_warnings(session, settings, body.unit_serial)
    return RunCreated(id=live.id, bench=live.extra.get("bench"), warnings=warnings)


@router.get("", response_model=list[RunOut])
def runs(
    session: SessionDep,
    runner: RunnerDep,
    _: ViewerDep,
    unit_serial: Annotated[str | None, Query(max_length=64)] = None,
    state: RunStateName | None = None,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
    offset: Annotated[
        int, Query(ge=0, le=MAX_PAGE_OFFSET, description="runs skipped from the newest (paging)")
    ] = 0,
    procedure: Annotated[str | None, Query(max_length=64)] = None,
    q: Annotated[str | None, Query(max_length=64, description="text in the run id or unit serial")] = None,
) -> list[RunOut]:
    """Runs, newest first (queued ones included: every run is stored from its request on),
    filtered by unit, state, procedure and a text in the run id or serial; paged by
    ``limit`` and ``offset``."""
    with session.begin():
        rows = list_runs(
            session,
            unit_serial=unit_serial,
            states=[state] if state else None,
            limit=limit,
            offset=offset,
            procedure=procedure,
            search=q,
        )
        ids = [r.id for r in rows]
        found = session.execute(
            sa.select(Certificate.run_id, Certificate.number).where(Certificate.run_id.in_(ids))
        ).all()
        numbers = dict(found)
        results = results_of_runs(session, ids)
        return [
            run_out(r, r.unit.serial, runner.live(r.id), numbers.get(r.id), results=results[r.id])
            for r in rows
        ]


@router.get("/{run_id}", response_model=RunOut, responses={404: {"description": "no such run"}})
def run(run_id: str, session: SessionDep, runner: RunnerDep, settings: SettingsDep, _: ViewerDep) -> RunOut:
    """One run: state, progress 0..1, outcome, error, the fit and the diagnosis (the
    ``calbench diagnose --json`` object, findings included) when there are."""
    with session.begin():
        row = get_run(session, run_id, with_unit=True)
        if row is not None:
            cert = session.execute(
                sa.select(Certificate.number, Certificate.content).where(Certificate.run_id == run_id)
            ).first()
            return run_out(
                row,
                row.unit.serial,
                runner.live(run_id),
                cert.number if cert is not None else None,
                results=results_of_runs(session, [run_id])[run_id],
                with_diagnosis=True,
                windows=list_windows(session, run_id),
                audit=run_audit(session, run_id),
                certificate_content=cert.content if cert is not None else None,
            )
    live = runner.live(run_id)
    if live is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} not found")
    return live_out(live, settings.bench_name)


@router.get(
    "/{run_id}/audit", response_model=list[AuditEntryOut], responses={404: {"description": "no such run"}}
)
def audit(run_id: str, session: SessionDep, _: ViewerDep) -> list[AuditEntryOut]:
    """Every action on the run, oldest first: who (the operator named by the token, ``agent`` or
    ``system``), when (UTC) and what (a request, or the state it moved to and why)."""
    with session.begin():
        if get_run(session, run_id) is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} not found")
        return [audit_out(a) for a in run_audit(session, run_id)]


@router.post(
    "/{run_id}/abort",
    response_model=AbortOut,
    responses={404: {"description": "no such run"}, 409: {"description": "the run is not live"}},
)
def abort(run_id: str, session: SessionDep, runner: RunnerDep, who: OperatorPrincipalDep) -> AbortOut:
    """Abort a live run: the table goes to its safe state, the recording is kept. A run still
    queued ends at once (``state`` ``aborted``); a live one is stopped by the bench's agent."""
    if runner.abort(run_id, actor=who.actor):
        with session.begin():
            row = get_run(session, run_id)
            state = row.state if row is not None else RunState.RUNNING
        return AbortOut(id=run_id, abort_requested=True, state=state)
    raise _not_live(session, run_id, "nothing to abort")


_NOT_LIVE: dict[int | str, dict[str, Any]] = {
    404: {"description": "no such run"},
    409: {"description": "the run does not hold the bench"},
}


def _not_live(session: SessionDep, run_id: str, what: str) -> HTTPException:
    with session.begin():
        row = get_run(session, run_id)
        if row is None:
            return HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} not found")
        state = row.state.value
        since = finishing_since(session, run_id) if state == "running" else None
    if since is not None:
        detail = (
            f"run {run_id} is finishing (every step done since {since}; safe state, fit and results "
            f"being stored): {what}"
        )
    else:
        where = "" if state == "running" else ", not running on this bench"
        detail = f"run {run_id} is {state}{where}: {what}"
    return HTTPException(status.HTTP_409_CONFLICT, detail)


@router.post("/{run_id}/pause", response_model=RunActionOut, responses=_NOT_LIVE)
def pause(run_id: str, session: SessionDep, runner: RunnerDep, who: OperatorPrincipalDep) -> RunActionOut:
    """Hold the live run: the table stops, the window in progress is dropped and recorded again
    when the run continues (``POST /api/runs/{id}/resume``). A run still waiting in the queue
    is held as soon as its agent starts it. Idempotent."""
    if runner.pause(run_id, actor=who.actor):
        return RunActionOut(id=run_id, action="pause", state=RunState.PAUSED)
    raise _not_live(session, run_id, "nothing to pause")


@router.post(
    "/{run_id}/resume",
    status_code=status.HTTP_202_ACCEPTED,
    response_model=RunActionOut,
    responses={
        404: {"description": "no such run"},
        409: {
            "description": "the run cannot be resumed: its state or recording, or its procedure "
            "(unknown here, not rebuilt from its stored parameters, or what remains breaks the "
            "table's limits) says why"
        },
    },
)
def resume(run_id: str, session: SessionDep, runner: RunnerDep, who: OperatorPrincipalDep) -> RunActionOut:
    """Continue a run. A paused or suspended run holding the bench goes on (for a suspension,
    the operator's go-ahead: the table is prepared again once the interlock has closed). An
    ``interrupted`` run (its process died or the service shut down) is queued on its bench and
    continues from the window after its last complete one (after the runs queued before it),
    with live events on ``/events`` and its certificate issued at the end as for a fresh run."""
    cur = runner.current
    if cur is not None and cur.id == run_id:
        # accepted while paused or suspended, or right after a pause its agent has not applied yet
        if not runner.continue_run(run_id, actor=who.actor):
            raise _not_live(session, run_id, "nothing to resume (no pause in effect or asked)")
        return RunActionOut(id=run_id, action="continue", state=RunState.RUNNING)
    try:
        live = runner.resume(run_id, actor=who.actor)
    except LookupError as exc:
        raise HTTPException(status.HTTP_404_NOT_FOUND, str(exc)) from None
    except (NotResumable, ResumeRefused) as exc:
        raise HTTPException(status.HTTP_409_CONFLICT, str(exc)) from None
    return RunActionOut(
        id=run_id,
        action="resume",
        state=RunState.QUEUED,
        resumed_from_window=live.extra.get("resumed_from_window"),
    )


@router.get(
    "/{run_id}/events",
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}, "description": "server-sent events"}},
)
async def events(
    run_id: str, request: Request, services: ServicesDep, who: ViewerLinkDep
) -> StreamingResponse:
    """Live progress as server-sent events: ``state``, ``progress``, ``window``, and a final
    ``finished`` (state, outcome, error, certificate_number) after which the stream ends; a
    ``shutdown`` event ends it when the service stops (the run is then ``interrupted``) or when
    the token it was opened with is revoked (checked every few seconds). A run that is already
    final gets one ``finished`` event with its stored state. A browser opens it with a signed
    link (``POST /api/links``) or with fetch and the Authorization header.

    The events come from the database, where the bench's agent writes them (whichever
    process this is, and also after it restarted mid-run): on PostgreSQL a notification of the
    write wakes the stream at once (LISTEN/NOTIFY, :mod:`api.runs.wakeup`), on SQLite it reads
    the run every ``EVENT_POLL_S``; one read serves all the streams of this process
    (:class:`api.runs.events.SnapshotCache`), in a worker thread, never on the event loop."""
    snapshots = services.snapshots or SnapshotCache(services.read_sessions)
    wakeups = services.wakeups
    waiter = wakeups.subscribe(run_id)  # before the first read: no change falls between the two
    try:
        first = await run_in_threadpool(snapshots.get, run_id)
    except BaseException:
        wakeups.unsubscribe(waiter)
        raise
    if first is None:
        wakeups.unsubscribe(waiter)
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"run {run_id} not found")

    async def read() -> RunSnapshot | None:
        return await run_in_threadpool(snapshots.get, run_id)

    async def token_live() -> bool:
        return bool(await anyio.to_thread.run_sync(services.auth.is_live, who))

    async def stream() -> AsyncIterator[str]:
        try:
            async for chunk in run_events(
                first,
                read=read,
                waiter=waiter,
                poll_s=lambda: wakeups.poll_s,
                closed=lambda: services.hub.closed,
                token_live=token_live,
                disconnected=request.is_disconnected,
            ):
                yield chunk
        finally:
            wakeups.unsubscribe(waiter)

    return StreamingResponse(stream(), media_type="text/event-stream", headers={"Cache-Control": "no-cache"})
