"""Whether a stored run may be resumed on this bench now: the one check every resume passes
before it claims the run — ``calbench resume``, ``POST /api/runs/{id}/resume``, the agent's
automatic resume — so that a run the bench can no longer continue is refused with the reason
instead of failing on the bench.

The procedure is rebuilt from the parameters stored with the run and what remains of it is
walked against the table's limits the bench runs with now
(:func:`bench.procedures.resume_check.check_resume`): a run recorded with a procedure this
version does not know (another version, another bench's calbench), whose stored parameters the
procedure no longer accepts, or whose remaining poses and rates no longer fit is refused with
:class:`ResumeRefused`, naming the run, the procedure and why. The run is left as it was.
"""

from __future__ import annotations

from typing import Any

from bench.procedures import Admitted, ProcedureRefused, Refusal, TableLimits
from bench.procedures.resume_check import check_resume, stored_parameters
from db.models import Run
from db.models import run_params as rp
from station.execution.devices import table_limits
from station.settings import Settings


class ResumeRefused(ProcedureRefused):
    """A resume the check refuses (a ``ValueError``: ``calbench resume`` exits 2 with its one
    line; the REST resume answers 409 with it). :ivar refusal: kind, procedure and message."""

    def __init__(self, refusal: Refusal, run_id: str) -> None:
        super().__init__(refusal)
        self.run_id = run_id


def stored_request(run: Run) -> dict[str, Any]:
    """The procedure parameters stored with ``run`` (``dwell_s`` included: the procedure's, else
    the dwell its request asked for)."""
    stored = run.params.get(rp.PARAMETERS) if isinstance(run.params, dict) else None
    out = dict(stored) if isinstance(stored, dict) else {}
    if out.get("dwell_s") is None and run.requested_dwell_s is not None:
        out["dwell_s"] = run.requested_dwell_s
    return out


def admit_stored(
    run_id: str, procedure: str, stored: dict[str, Any], next_window: int, limits: TableLimits
) -> Admitted:
    """:func:`~bench.procedures.resume_check.check_resume`, raising its refusal.

    :raises ResumeRefused: the procedure is unknown, does not rebuild, or what remains from
        window ``next_window`` breaks ``limits``.
    """
    checked = check_resume(procedure, limits, stored=stored, next_window=next_window, run_id=run_id)
    if isinstance(checked, Refusal):
        raise ResumeRefused(checked, run_id)
    return checked


def admit_resume(settings: Settings, run: Run, sim: bool | None = None) -> Admitted:
    """The check of a stored run before it is claimed: its procedure from the window after its
    last complete one, against this bench's limits (:func:`admit_stored`,
    :func:`~station.execution.devices.table_limits`; ``sim``: a simulated bench, default
    ``settings.sim``).

    :raises ResumeRefused: why it cannot continue here (the run is left as it was).
    """
    last = run.last_complete_window
    next_window = 0 if last is None else last + 1
    return admit_stored(run.id, run.procedure, stored_request(run), next_window, table_limits(settings, sim))


def request_keywords(run_id: str, procedure: str, stored: dict[str, Any]) -> dict[str, Any]:
    """The factory keywords of a stored request (a run that never recorded starts with them).

    :raises ResumeRefused: no procedure of that name is registered (run and name named).
    """
    kw = stored_parameters(procedure, stored, run_id)
    if isinstance(kw, Refusal):
        raise ResumeRefused(kw, run_id)
    return kw
