"""The lab's benches as the API sees them: which have a live agent, what each can run, how busy
each is, and which one a run goes to.

A bench's agent calls :func:`agent_alive` every few seconds (and :func:`agent_gone` when it
stops); an agent not seen for ``stale_after_s`` is taken as offline. An agent of this host is
offline at once when its process is gone (killed, crashed): the agent records its pid and the
start time of its process (:mod:`db.process`), so a later process that was given the same pid
is not taken for it; an agent of another host keeps the staleness rule. :func:`bench_status`
lists every bench with its state (``idle``, ``busy`` or ``offline``), the run holding it and
its queue; :func:`choose_bench` picks the bench of a run the client left to the service.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import socket
from collections.abc import Callable, Sequence
from typing import Any, Literal

import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import Bench, Run, RunState
from db.process import same_process_alive
from db.types import utc_now

AGENT_STALE_S = 30.0
"""An agent not seen for this long is offline (s); agents report every few seconds."""
HOLDING = (RunState.RUNNING, RunState.PAUSED, RunState.SUSPENDED)
START_KEY = "agent_start_ticks"
"""Key of ``Bench.info`` holding the start time of the agent's process (:mod:`db.process`)."""

BenchState = Literal["idle", "busy", "offline"]


@dataclasses.dataclass(frozen=True)
class BenchStatus:
    """One bench now.

    :param state: ``offline`` (no live agent), ``busy`` (a run holds it) or ``idle``.
    :param procedures: the procedures its agent says the table can run (empty: not known).
    :param bench_file: the identity of its bench file (name, version, sha256, path), if told.
    :param holding_run: the run holding the bench; :param n_queued: runs waiting for it.
    """

    name: str
    state: BenchState
    agent_seen_at: dt.datetime | None
    agent_host: str | None
    procedures: tuple[str, ...]
    bench_file: dict[str, Any] | None
    holding_run: str | None
    n_queued: int

    def can_run(self, procedure: str) -> bool:
        """Its agent lists ``procedure`` (or lists nothing: not known, assumed)."""
        return not self.procedures or procedure in self.procedures


def agent_alive(
    session: Session,
    bench_id: int,
    *,
    pid: int,
    host: str,
    procedures: Sequence[str],
    bench_file: dict[str, Any] | None,
    start_ticks: int | None = None,
    now: dt.datetime | None = None,
) -> None:
    """The bench's agent ``pid@host`` is alive now and its table can run ``procedures``.

    :param start_ticks: the start time of the agent's process (:func:`db.process.process_start_ticks`),
        so that an API on the same host tells it from a later process with the same pid.
    """
    bench = session.get(Bench, bench_id, with_for_update=True)
    if bench is None:
        raise LookupError(f"bench {bench_id} not found")
    bench.agent_seen_at, bench.agent_pid, bench.agent_host = now or utc_now(), pid, host
    info = {"procedures": list(procedures), "bench_file": bench_file, START_KEY: start_ticks}
    if bench.info and "lease" in bench.info:  # the bench's lease (db.repo.lease) is not the agent's report
        info["lease"] = bench.info["lease"]
    if bench.info != info:
        bench.info = info
    session.flush()


def agent_gone(session: Session, bench_id: int, *, pid: int, host: str) -> None:
    """The agent ``pid@host`` stopped: its bench is offline at once (another agent's record stays)."""
    session.execute(
        sa.update(Bench)
        .where(Bench.id == bench_id, Bench.agent_pid == pid, Bench.agent_host == host)
        .values(agent_seen_at=None)
        .execution_options(synchronize_session="fetch")
    )


AgentCheck = Callable[[int, int | None], bool]
"""``(pid, start_ticks) -> alive``: whether an agent process of this host still runs."""


def agent_online(
    bench: Bench,
    now: dt.datetime,
    *,
    stale_after_s: float = AGENT_STALE_S,
    host: str | None = None,
    is_alive: AgentCheck = same_process_alive,
) -> bool:
    """Whether the bench has a live agent: seen within ``stale_after_s``, and, when the agent is
    of this ``host`` (default: this machine's name), its process (pid and start time) still runs."""
    seen = bench.agent_seen_at
    if seen is None or (now - seen).total_seconds() > stale_after_s:
        return False
    here = host if host is not None else socket.gethostname()
    if bench.agent_host != here or bench.agent_pid is None:
        return True
    start = (bench.info or {}).get(START_KEY)
    return is_alive(bench.agent_pid, start if isinstance(start, int) else None)


def bench_status(
    session: Session,
    *,
    now: dt.datetime | None = None,
    stale_after_s: float = AGENT_STALE_S,
    host: str | None = None,
    is_alive: AgentCheck = same_process_alive,
) -> list[BenchStatus]:
    """Every bench, by name; a bench is ``offline`` as :func:`agent_online` says."""
    now = now or utc_now()
    benches = list(session.scalars(sa.select(Bench).order_by(Bench.name)))
    held = session.execute(sa.select(Run.bench_id, Run.id).where(Run.state.in_(HOLDING))).all()
    holding: dict[int | None, str] = {row.bench_id: row.id for row in held}
    queued: dict[int | None, int] = {
        bench_id: int(n)
        for bench_id, n in session.execute(
            sa.select(Run.bench_id, sa.func.count())
            .where(Run.state == RunState.QUEUED, Run.owner_pid.is_(None))
            .group_by(Run.bench_id)
        ).all()
    }
    out = []
    for b in benches:
        seen = b.agent_seen_at
        online = agent_online(b, now, stale_after_s=stale_after_s, host=host, is_alive=is_alive)
        run_id = holding.get(b.id)
        state: BenchState = "offline" if not online else "busy" if run_id is not None else "idle"
        info = b.info or {}
        procedures = info.get("procedures") or []
        bench_file = info.get("bench_file")
        out.append(
            BenchStatus(
                b.name,
                state,
                seen,
                b.agent_host,
                tuple(str(p) for p in procedures),
                bench_file if isinstance(bench_file, dict) else None,
                run_id,
                queued.get(b.id, 0),
            )
        )
    return out


def find_bench(statuses: Sequence[BenchStatus], name: str) -> BenchStatus:
    """The bench called ``name`` in the database, else the one whose bench file is called so.

    :raises LookupError: no such bench, or several bench files with that name (named).
    """
    for s in statuses:
        if s.name == name:
            return s
    by_file = [s for s in statuses if s.bench_file is not None and s.bench_file.get("name") == name]
    if len(by_file) == 1:
        return by_file[0]
    known = ", ".join(s.name for s in statuses) or "none"
    if by_file:
        raise LookupError(
            f"bench {name!r} is the bench file of several benches ({', '.join(s.name for s in by_file)}): "
            "give the bench's name"
        )
    raise LookupError(f"bench {name!r} unknown; known benches: {known}")


def choose_bench(statuses: Sequence[BenchStatus], procedure: str, prefer: str) -> str | None:
    """The bench for a run the client left to the service: among the benches with a live agent
    that can run ``procedure``, a free one (nothing holding it, nothing queued), else the one
    with the fewest runs ahead; ties go to ``prefer`` (the API's own bench), then by name.
    ``None`` when no bench with a live agent can run it."""
    able = [s for s in statuses if s.state != "offline" and s.can_run(procedure)]
    if not able:
        return None

    def load(s: BenchStatus) -> tuple[int, bool, str]:
        return (s.n_queued + (s.holding_run is not None), s.name != prefer, s.name)

    return min(able, key=load).name
