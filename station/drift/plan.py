"""Where each drift check goes: the bench of the unit when that bench has a live agent that can
run the check's procedure; otherwise the unit is not checked, and why.

A unit's bench is the one it was last run on (``Unit.bench_id``, where it is mounted), else the
bench of its latest certificate (:func:`station.drift.record.certificate_bench`). Nothing here
queues a run: :class:`station.drift.scheduler.DriftScheduler` queues the checks of :func:`plan_checks`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from db.repo.benches import BenchStatus, find_bench


@dataclasses.dataclass(frozen=True)
class DueUnit:
    """A unit to check and the name of its bench (``None``: no bench known)."""

    unit_serial: str
    bench: str | None


@dataclasses.dataclass(frozen=True)
class DriftTarget:
    """A drift check to queue: the unit and the bench (its database name) it runs on."""

    unit_serial: str
    bench: str


@dataclasses.dataclass(frozen=True)
class NotChecked:
    """A unit whose drift check was not queued: its bench (if known) and why, in words."""

    unit_serial: str
    bench: str | None
    reason: str


def plan_checks(
    units: Sequence[DueUnit], statuses: Sequence[BenchStatus], procedure: str
) -> tuple[list[DriftTarget], list[NotChecked]]:
    """Split ``units`` into the checks to queue (in the order given) and those not checked.

    :param statuses: every bench now (:func:`db.repo.benches.bench_status`).
    :param procedure: the drift check's procedure.
    """
    targets: list[DriftTarget] = []
    skipped: list[NotChecked] = []
    for unit in units:
        if unit.bench is None:
            skipped.append(NotChecked(unit.unit_serial, None, "no bench is known for the unit"))
            continue
        try:
            status = find_bench(statuses, unit.bench)
        except LookupError as exc:
            skipped.append(NotChecked(unit.unit_serial, unit.bench, str(exc)))
            continue
        if status.state == "offline":
            seen = status.agent_seen_at.isoformat() if status.agent_seen_at else "never"
            why = f"bench {status.name!r} has no live agent (last seen: {seen})"
            skipped.append(NotChecked(unit.unit_serial, status.name, why))
        elif not status.can_run(procedure):
            why = f"bench {status.name!r} cannot run {procedure}; it runs {', '.join(status.procedures)}"
            skipped.append(NotChecked(unit.unit_serial, status.name, why))
        else:
            targets.append(DriftTarget(unit.unit_serial, status.name))
    return targets, skipped
