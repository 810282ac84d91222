"""A run whose devices do not answer: it is left ``interrupted`` with an error beginning
:data:`~station.execution.fault_retry.FAULT_PREFIX` that names the device and the fault, for
the retry policy (:mod:`station.execution.fault_retry`) or an operator to resume.

A run the service queued is stored before its devices open; one ``calbench run`` starts is
stored only once they answer, so a bench that does not answer at the start of ``calbench run``
stores the request (:class:`StartRequest`) as an ``interrupted`` run: resuming it starts it
as it was requested, as the service's agent does.
"""

from __future__ import annotations

import dataclasses
import os
import socket
from pathlib import Path
from typing import Any

from sqlalchemy.orm import Session

from bench.bench_config import BenchConfig
from bench.sequencer.faults import resumable_fault
from db.models import Run
from db.models import RunState as DbRunState
from db.repo.audit import command_line_actor
from db.repo.recovery import mark_run_interrupted
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from station.execution.devices import DeviceNotAnswering
from station.execution.fault_retry import FAULT_PREFIX
from station.settings import Settings


def bench_urls(config: BenchConfig) -> dict[str, str | None]:
    """The ``bench`` row's device URLs: the bench file's, none for the simulated bench."""
    return {} if config.simulated else {"table_url": config.table_url, "daq_url": config.daq_url}


@dataclasses.dataclass(frozen=True)
class StartRequest:
    """What :func:`start_run` was asked, to store a run whose devices did not open before it
    was stored (``calbench run``): its resume starts it as it was requested."""

    settings: Settings
    bench_config: BenchConfig
    unit_serial: str
    procedure: str
    meta: dict[str, Any]
    csv_path: Path
    dwell_s: float | None

    def store_interrupted(self, s: Session, run_id: str, why: str) -> None:
        """Add the run, its unit and bench, and leave it ``interrupted`` with ``why``."""
        bench = get_or_create_bench(s, self.settings.bench_name, **bench_urls(self.bench_config))
        unit = get_or_create_unit(
            s, self.unit_serial, channel_unit=self.bench_config.channel_unit, bench_id=bench.id
        )
        run = create_run(
            s,
            run_id,
            unit.id,
            self.procedure,
            bench_id=bench.id,
            params=self.meta,
            recording_path=str(self.csv_path),
            state=DbRunState.RUNNING,
            owner_pid=os.getpid(),
            owner_host=socket.gethostname(),
        )
        run.requested_dwell_s = self.dwell_s
        s.flush()
        mark_run_interrupted(s, run_id, why, actor=command_line_actor())


def fault_text(exc: Exception, what: str) -> str:
    """The stored error of a run ``what`` stopped (the device named when it is known)."""
    cause = str(exc) if isinstance(exc, DeviceNotAnswering) else f"{type(exc).__name__}: {exc}"
    return f"{FAULT_PREFIX}{what}: {cause}"


def interrupt_if_not_answering(
    sessions: Any,
    run_id: str,
    exc: Exception,
    what: str = "the devices did not open",
    *,
    request: StartRequest | None = None,
) -> str | None:
    """When ``what`` failed with a fault the bench recovers from (the bench not answering, a
    simulator that did not start, a full disk), leave the run ``interrupted`` with an error
    beginning :data:`FAULT_PREFIX`, for the next try of the retry policy, and return why;
    ``None`` for any other error, or a run not stored live. A run not stored yet
    (``calbench run`` before its first write) is stored ``interrupted`` from ``request``."""
    if not (resumable_fault(exc) or isinstance(exc, RuntimeError)):
        return None
    why = fault_text(exc, what)
    with sessions.begin() as s:
        if request is not None and s.get(Run, run_id) is None:
            request.store_interrupted(s, run_id, why)
            return why
        return why if mark_run_interrupted(s, run_id, why) else None
