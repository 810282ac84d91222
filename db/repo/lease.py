"""The bench lease: which process drives a bench's table, across hosts, with a fencing token.

The OS lock of a data directory (:mod:`station.execution.bench_lock`) keeps two processes of one host
off one table; agents of several hosts sharing one PostgreSQL database would each hold their
own. The lease is the database's word on it: ``Bench.info["lease"] = {"token", "holder",
"expires_at"}``, written in one transaction with the bench row locked (``SELECT … FOR
UPDATE`` on PostgreSQL; SQLite's writing transactions begin ``IMMEDIATE`` and are alone).

* :func:`acquire_lease` takes a free or expired lease, or one whose holder was a process of
  this host that is gone (pid and start time, :mod:`db.process`), and returns a new token,
  one more than any before: a **fencing token**. A lease held by a live process is refused
  with :class:`LeaseHeld` naming it.
* :func:`renew_lease` extends it (every ``ttl_s / 3``); a holder whose token is no longer
  the bench's has lost the lease (it stalled past ``ttl_s`` and another took over) and must
  stop driving the table.
* :func:`lease_is_current` is the fence: the agent claims a run only while its token is the
  bench's (:func:`db.repo.queue.claim_next_run`), so a holder that lost its lease cannot
  start a run however late it wakes.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import socket
from collections.abc import Callable
from typing import Any

from sqlalchemy.orm import Session

from db.models import Bench
from db.process import same_process_alive
from db.types import utc_now

LEASE_KEY = "lease"
"""Key of ``Bench.info`` holding the lease."""
LEASE_TTL_S = 30.0
"""How long a lease lasts without renewal (s); the agents' staleness rule uses the same 30 s."""


@dataclasses.dataclass(frozen=True)
class LeaseHolder:
    """The process holding (or asking for) a bench.

    :param kind: what it is: ``calbench agent``, ``calbench run``, ``calbench resume``,
        ``calbench serve`` (embedded agent).
    :param since: when it took the bench (UTC).
    :param start_ticks: its process's start time (:func:`db.process.process_start_ticks`).
    """

    pid: int
    host: str
    kind: str
    since: dt.datetime
    start_ticks: int | None = None

    def describe(self) -> str:
        """``calbench agent pid 123 on host lab-1 since 2026-11-27T06:20:00Z``."""
        since = self.since.astimezone(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
        return f"{self.kind} pid {self.pid} on host {self.host} since {since}"

    def to_json(self) -> dict[str, Any]:
        """The holder as stored (JSON)."""
        return {
            "pid": self.pid,
            "host": self.host,
            "kind": self.kind,
            "since": self.since.isoformat(),
            "start_ticks": self.start_ticks,
        }

    @classmethod
    def from_json(cls, raw: object) -> LeaseHolder | None:
        """The holder stored as :meth:`to_json`; ``None`` when it cannot be read."""
        if not isinstance(raw, dict):
            return None
        try:
            since = dt.datetime.fromisoformat(str(raw["since"]))
            ticks = raw.get("start_ticks")
            return cls(
                int(raw["pid"]),
                str(raw["host"]),
                str(raw["kind"]),
                since if since.tzinfo else since.replace(tzinfo=dt.UTC),
                int(ticks) if isinstance(ticks, int) else None,
            )
        except (KeyError, TypeError, ValueError):
            return None


class LeaseHeld(RuntimeError):
    """Another live process holds the bench (its holder named, one line)."""

    def __init__(self, bench: str, holder: LeaseHolder | None, expires_at: dt.datetime | None) -> None:
        self.holder = holder
        who = holder.describe() if holder is not None else "a process that cannot be named"
        until = f", lease until {expires_at:%H:%M:%S}Z" if expires_at is not None else ""
        super().__init__(f"bench {bench!r} is driven by {who} (database lease{until})")


ProcessCheck = Callable[[int, int | None], bool]
"""``(pid, start_ticks) -> alive`` for a process of this host."""


def _lease(bench: Bench) -> tuple[int, LeaseHolder | None, dt.datetime | None]:
    raw = (bench.info or {}).get(LEASE_KEY)
    if not isinstance(raw, dict):
        return 0, None, None
    token = raw.get("token")
    token = token if isinstance(token, int) else 0
    try:
        expires = dt.datetime.fromisoformat(str(raw["expires_at"]))
    except (KeyError, TypeError, ValueError):
        return token, None, None
    expires = expires if expires.tzinfo else expires.replace(tzinfo=dt.UTC)
    return token, LeaseHolder.from_json(raw.get("holder")), expires


def _store(bench: Bench, token: int, holder: LeaseHolder | None, expires_at: dt.datetime | None) -> None:
    lease = {
        "token": token,
        "holder": holder.to_json() if holder is not None else None,
        "expires_at": expires_at.isoformat() if expires_at is not None else None,
    }
    bench.info = {**(bench.info or {}), LEASE_KEY: lease}


def _locked_bench(session: Session, bench_id: int) -> Bench:
    bench = session.get(Bench, bench_id, with_for_update=True, populate_existing=True)
    if bench is None:
        raise LookupError(f"bench {bench_id} not found")
    return bench


def acquire_lease(
    session: Session,
    bench_id: int,
    holder: LeaseHolder,
    *,
    ttl_s: float = LEASE_TTL_S,
    now: dt.datetime | None = None,
    is_alive: ProcessCheck = same_process_alive,
    host: str | None = None,
) -> int:
    """Take the bench's lease for ``holder``; its fencing token.

    Free when nobody holds it, when it expired, or when its holder was a process of this
    ``host`` (default this machine) that no longer runs.

    :raises LeaseHeld: a live process holds it (named).
    :raises LookupError: no bench ``bench_id``.
    """
    now = now or utc_now()
    bench = _locked_bench(session, bench_id)
    token, current, expires = _lease(bench)
    here = host if host is not None else socket.gethostname()
    if current is not None and expires is not None and expires > now:
        gone = current.host == here and not is_alive(current.pid, current.start_ticks)
        mine = (current.pid, current.host, current.start_ticks) == (
            holder.pid,
            holder.host,
            holder.start_ticks,
        )
        if not (gone or mine):
            raise LeaseHeld(bench.name, current, expires)
    _store(bench, token + 1, holder, now + dt.timedelta(seconds=ttl_s))
    session.flush()
    return token + 1


def renew_lease(
    session: Session, bench_id: int, token: int, *, ttl_s: float = LEASE_TTL_S, now: dt.datetime | None = None
) -> bool:
    """Extend the lease ``token`` by ``ttl_s`` from now; False when it is no longer the bench's
    (another process took the bench after it expired: stop driving the table)."""
    bench = _locked_bench(session, bench_id)
    current, holder, _expires = _lease(bench)
    if current != token or holder is None:
        return False
    _store(bench, token, holder, (now or utc_now()) + dt.timedelta(seconds=ttl_s))
    session.flush()
    return True


def release_lease(session: Session, bench_id: int, token: int) -> None:
    """Give the lease ``token`` back (nothing when it is no longer the bench's); the token count
    stays, so the next holder's token is larger."""
    bench = session.get(Bench, bench_id, with_for_update=True, populate_existing=True)
    if bench is None or _lease(bench)[0] != token:
        return
    _store(bench, token, None, None)
    session.flush()


def lease_is_current(session: Session, bench_id: int, token: int, *, now: dt.datetime | None = None) -> bool:
    """The fence: ``token`` is the bench's lease and has not expired."""
    bench = session.get(Bench, bench_id, populate_existing=True)
    if bench is None:
        return False
    current, holder, expires = _lease(bench)
    return current == token and holder is not None and expires is not None and expires > (now or utc_now())
