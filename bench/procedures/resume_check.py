"""The check a resume passes before it continues a stored run: the procedure it was recorded
with is still known, rebuilds from its stored parameters, and the steps still to run fit the
table's limits now.

A run is resumed later than it started — after a fault, a restart, a deploy of a newer
version, on a bench whose limits were changed — so what admitted it at its start
(:func:`~bench.procedures.registry.check_procedure`) is asked again of what remains: the
:class:`~bench.procedures.steps.MoveTo` that brings the table to the next window's pose and
every step from that window on (:meth:`~bench.procedures.steps.Procedure.resume_plan`, the
sequencer's own restart point). Windows already recorded are not walked again: a limit they
would break now does not spoil what they measured.

:func:`check_resume` answers :class:`~bench.procedures.registry.Admitted` (the whole procedure
and the walk of what remains) or a :class:`~bench.procedures.registry.Refusal` whose message
names the run and the procedure.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from bench.procedures.preview import TableLimits, preview
from bench.procedures.registry import PROCEDURES, Admitted, Refusal, RefusalKind, accepted_parameters
from bench.procedures.steps import Procedure


def stored_parameters(name: str, stored: Mapping[str, Any], run_id: str) -> dict[str, Any] | Refusal:
    """The factory keywords of procedure ``name`` from a run's stored parameters: the ones the
    factory takes and not null, JSON lists as tuples (``dwell_s`` is not one of them).

    :returns: the keywords, or a :class:`Refusal` (``UNKNOWN_PROCEDURE``) when no procedure of
        that name is registered — a run stored by another version or another bench's
        calbench — naming the run and the procedures this version knows.
    """
    factory = PROCEDURES.get(name)
    if factory is None:
        known = ", ".join(sorted(PROCEDURES))
        return Refusal(
            RefusalKind.UNKNOWN_PROCEDURE,
            name,
            f"run {run_id} was recorded with procedure {name!r}, which this calbench does not know "
            f"(known: {known}): it cannot be rebuilt to continue; the run stays as it is",
        )
    accepted = accepted_parameters(factory)
    out = {k: v for k, v in stored.items() if k in accepted and v is not None}
    for k, v in list(out.items()):
        if isinstance(v, list):
            out[k] = tuple(tuple(x) if isinstance(x, list) else x for x in v)
    return out


def remaining(proc: Procedure, next_window: int) -> Procedure:
    """The steps a resume at window ``next_window`` runs: the move to its pose (if any) and every
    step from that window on.

    :raises ValueError: ``next_window`` outside 0..n_windows.
    """
    start, move = proc.resume_plan(next_window)
    steps = ((proc.steps[move],) if move is not None else ()) + proc.steps[start:]
    return Procedure(proc.name, steps, proc.parameters, proc.n_axes)


def check_resume(
    name: str,
    limits: TableLimits,
    *,
    stored: Mapping[str, Any],
    next_window: int,
    run_id: str,
) -> Admitted | Refusal:
    """Rebuild procedure ``name`` from a run's stored parameters (``stored``: its ``parameters``
    object, ``dwell_s`` included) and walk what remains from window ``next_window`` against
    ``limits``.

    :returns: :class:`Admitted` with the whole procedure and the walk of what remains, or the
        first :class:`Refusal` in the order name, values, table limits; every message names
        the run.
    """
    kw = stored_parameters(name, stored, run_id)
    if isinstance(kw, Refusal):
        return kw
    dwell = stored.get("dwell_s")
    dwell_s = float(dwell) if isinstance(dwell, int | float) else None
    try:
        proc = PROCEDURES[name](dwell_s=dwell_s, **kw)
        rest = remaining(proc, next_window)
    except (TypeError, ValueError) as exc:
        return Refusal(
            RefusalKind.BAD_VALUE,
            name,
            f"run {run_id}: procedure {name!r} does not rebuild from its stored parameters: {exc}",
        )
    walk = preview(rest, limits, check_plan=False)
    if not walk.ok:
        return Refusal(
            RefusalKind.TABLE_LIMITS,
            name,
            f"run {run_id}: the {rest.n_windows} windows of {name} still to record (from window "
            f"{next_window + 1} of {proc.n_windows}) no longer fit the table's limits: "
            + "; ".join(walk.problems),
            walk,
        )
    return Admitted(proc, walk)
