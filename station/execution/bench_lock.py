"""One owner per bench: the lock held by whichever process drives the table.

The process that drives a bench's table — ``calbench agent``, ``calbench serve --agent
embedded``, ``calbench run``, ``calbench resume`` — holds its :class:`BenchLock` from before it
opens the devices until it has closed them. Any other process that asks for the bench is
refused with :class:`BenchHeld`, one line naming the holder (process kind, pid, host, since
when); the commands then exit with :data:`HELD_EXIT`.

Two locks, both taken or neither:

* the **OS lock**: ``fcntl.flock`` on ``<data_dir>/bench-<name>.lock`` (the kernel drops it
  when the process ends, however it ends). The file holds the holder as one JSON line, also
  the ``calbench serve`` that started an agent (``supervisor``), so a later service can tell
  an agent left behind by a killed service (adopted) from one a live service runs (never
  touched): :func:`read_holder`.
* the **database lease** with a fencing token (:mod:`db.repo.lease`), for agents of several
  hosts sharing one PostgreSQL database (one data directory each). It is renewed every
  ``LEASE_TTL_S / 3`` by a thread; a holder that finds its lease taken (it stalled for longer
  than the lease) is told through ``on_lost`` and must stop driving the table; the agent
  claims runs only under a current token (:func:`db.repo.queue.claim_next_run`).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import logging
import os
import re
import socket
import threading
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from bench.bench_config import load_bench_config
from db.engine import make_session_factory
from db.migrate import open_database
from db.process import process_start_ticks, same_process_alive
from db.repo.lease import LEASE_TTL_S, LeaseHeld, LeaseHolder, acquire_lease, release_lease, renew_lease
from db.repo.units import get_or_create_bench
from db.types import utc_now
from station.execution.device_lock import (
    Device,
    DeviceHeld,
    DeviceLocks,
    bench_devices,
    lock_dir,
    try_flock,
)
from station.settings import Settings

log = logging.getLogger(__name__)

HELD_EXIT = 3
"""Exit code of a command refused because another process drives the bench."""
SUPERVISOR_ENV = "CALBENCH_AGENT_SUPERVISOR"
"""Environment variable through which ``calbench serve`` tells the agent it starts who it is
(``"<pid>:<start ticks>"``); the agent writes it into its lock file."""


@dataclasses.dataclass(frozen=True)
class LockHolder:
    """The process named in a bench's lock file.

    :param supervisor: ``(pid, start ticks)`` of the ``calbench serve`` that started it, if any.
    """

    pid: int
    host: str
    kind: str
    since: dt.datetime
    start_ticks: int | None = None
    supervisor: tuple[int, int | None] | None = None

    def describe(self) -> str:
        """``calbench agent pid 123 on host lab-1 since 2026-11-27T06:20:00Z``."""
        return LeaseHolder(self.pid, self.host, self.kind, self.since).describe()

    def orphaned(self) -> bool:
        """An agent whose ``calbench serve`` is gone (killed): a new service may adopt it."""
        if self.supervisor is None:
            return False
        return not same_process_alive(*self.supervisor)


class BenchHeld(RuntimeError):
    """Another process drives the bench; the message is one line naming it."""


def lock_path(settings: Settings) -> Path:
    """The bench's lock file: ``<data_dir>/bench-<name>.lock``."""
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", settings.bench_name)[:100]
    return settings.data_dir / f"bench-{safe}.lock"


def _parse_holder(text: str) -> LockHolder | None:
    try:
        raw: Any = json.loads(text.splitlines()[0])
        since = dt.datetime.fromisoformat(raw["since"])
        sup = raw.get("supervisor")
        return LockHolder(
            int(raw["pid"]),
            str(raw["host"]),
            str(raw["kind"]),
            since,
            raw.get("start_ticks"),
            (int(sup[0]), sup[1]) if isinstance(sup, list) and len(sup) == 2 else None,
        )
    except (ValueError, KeyError, TypeError, IndexError):
        return None


def read_holder(path: Path) -> LockHolder | None:
    """The holder of the lock file ``path``; ``None`` when nobody holds it. (The check holds the
    lock for an instant: a process asking just then is refused, and a supervisor tries again.)
    A held lock whose file cannot be read gives a holder of pid -1."""
    handle = try_flock(path)
    if handle is not None:
        handle.close()
        return None
    try:
        text = path.read_text()
    except OSError:
        text = ""
    holder = _parse_holder(text)
    return holder or LockHolder(-1, "?", "an unknown process", utc_now())


def _supervisor_from_env() -> tuple[int, int | None] | None:
    raw = os.environ.get(SUPERVISOR_ENV, "")
    pid, _, ticks = raw.partition(":")
    try:
        return int(pid), (int(ticks) if ticks else None)
    except ValueError:
        return None


class BenchLock:
    """Hold the bench of ``settings`` for this process (see the module docstring).

    :param kind: what this process is, as the refusal names it (``calbench run``, …).
    :param lease: also hold the database lease (default).
    :param on_lost: called (from the renewal thread) when the lease was taken by another
        process; the holder must stop driving the table.
    :param sim: the process drives a simulated bench (``--sim``): no real device to lock.
    """

    def __init__(
        self,
        settings: Settings,
        kind: str,
        *,
        lease: bool = True,
        on_lost: Callable[[str], None] | None = None,
        ttl_s: float = LEASE_TTL_S,
        sim: bool = False,
    ) -> None:
        self.settings, self.kind, self.use_lease, self.on_lost, self.ttl_s = (
            settings,
            kind,
            lease,
            on_lost,
            ttl_s,
        )
        self.path = lock_path(settings)
        self.token: int | None = None
        self.bench_id: int | None = None
        self.lost = threading.Event()
        self._handle: IO[str] | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._engine: Any = None
        self.sim = sim or settings.sim
        self._devices: DeviceLocks | None = None

    def acquire(self) -> BenchLock:
        """Take the OS lock, the locks of the bench file's real devices, then the lease.

        :raises BenchHeld: another process holds any of them (named: the bench, or the device
            and the bench its holder drives it as).
        """
        handle = try_flock(self.path)
        if handle is None:
            holder = read_holder(self.path)
            who = holder.describe() if holder is not None else "another process"
            raise BenchHeld(f"bench {self.settings.bench_name!r} is driven by {who} (lock {self.path})")
        try:
            self._devices = DeviceLocks(
                self._real_devices(),
                lock_dir(self.settings.device_lock_dir),
                self.kind,
                self.settings.bench_name,
            ).acquire()
        except DeviceHeld as exc:
            handle.close()
            raise BenchHeld(f"bench {self.settings.bench_name!r}: {exc}") from None
        pid = os.getpid()
        me = LockHolder(pid, socket.gethostname(), self.kind, utc_now(), process_start_ticks(pid))
        record = {
            "pid": me.pid,
            "host": me.host,
            "kind": me.kind,
            "since": me.since.isoformat(),
            "start_ticks": me.start_ticks,
            "supervisor": list(sup) if (sup := _supervisor_from_env()) is not None else None,
        }
        handle.seek(0)
        handle.truncate()
        handle.write(json.dumps(record) + "\n")
        handle.flush()
        self._handle = handle
        if self.use_lease:
            try:
                self._take_lease(LeaseHolder(me.pid, me.host, me.kind, me.since, me.start_ticks))
            except BaseException:
                self.release()
                raise
        return self

    def _real_devices(self) -> list[Device]:
        """The real devices this process will drive: the bench file's, none for a simulated
        bench (``sim``) or a bench file that does not load (the run says why, later)."""
        if self.sim or self.settings.bench_file is None:
            return []
        try:
            return bench_devices(load_bench_config(self.settings.bench_file))
        except (OSError, ValueError):
            return []

    def _take_lease(self, holder: LeaseHolder) -> None:
        self._engine = open_database(self.settings.effective_database_url)
        self._sessions = make_session_factory(self._engine)
        try:
            with self._sessions.begin() as s:
                self.bench_id = get_or_create_bench(s, self.settings.bench_name).id
                self.token = acquire_lease(s, self.bench_id, holder, ttl_s=self.ttl_s)
        except LeaseHeld as exc:
            raise BenchHeld(str(exc)) from None
        self._thread = threading.Thread(target=self._renew, name="bench-lease", daemon=True)
        self._thread.start()

    def _renew(self) -> None:
        while not self._stop.wait(self.ttl_s / 3):
            assert self.bench_id is not None and self.token is not None
            try:
                with self._sessions.begin() as s:
                    kept = renew_lease(s, self.bench_id, self.token, ttl_s=self.ttl_s)
            except Exception:  # the database is away: the lease may lapse; the next renewal says
                log.warning("bench %s: could not renew the lease", self.settings.bench_name, exc_info=True)
                continue
            if not kept:
                why = f"the lease of bench {self.settings.bench_name!r} was taken by another process"
                log.error("%s; this process stops driving the table", why)
                self.lost.set()
                if self.on_lost is not None:
                    self.on_lost(why)
                return

    def release(self) -> None:
        """Give back the lease and the OS lock (idempotent)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        if self._engine is not None:
            if self.token is not None and self.bench_id is not None and not self.lost.is_set():
                try:
                    with self._sessions.begin() as s:
                        release_lease(s, self.bench_id, self.token)
                except Exception:  # it expires by itself
                    log.warning("bench %s: could not release the lease", self.settings.bench_name)
            self._engine.dispose()
            self._engine = None
        if self._devices is not None:
            self._devices.release()
            self._devices = None
        if self._handle is not None:
            self._handle.close()
            self._handle = None

    def __enter__(self) -> BenchLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()
