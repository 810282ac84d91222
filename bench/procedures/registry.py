"""Procedures by name: the registry, building one from its name and parameters, and the one
check a request to run it passes (known name, parameters it takes, values its factory accepts,
a walk the table's limits allow) before anything starts.

:func:`check_procedure` answers with the built procedure and its preview
(:class:`Admitted`) or with what refuses it and why (:class:`Refusal`); the interfaces map a
refusal's :class:`RefusalKind` to their status or exit code. :func:`admit_procedure` raises
the refusal as :class:`ProcedureRefused` (a ``ValueError``) for callers that refuse by raising.
"""

from __future__ import annotations

import enum
import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from bench.procedures.oscillation import oscillation_2axis
from bench.procedures.planned import planned_static, planned_tumble
from bench.procedures.preview import Preview, TableLimits, preview
from bench.procedures.rate import rate_1axis
from bench.procedures.static import static_12
from bench.procedures.steps import Procedure

PROCEDURES: dict[str, Callable[..., Procedure]] = {
    "static-12": static_12,
    "rate-1axis": rate_1axis,
    "oscillation-2axis": oscillation_2axis,
    "planned-static": planned_static,
    "planned-tumble": planned_tumble,
}
"""Registry: procedure name -> factory taking ``dwell_s`` (``None``: noise window first)."""


class RefusalKind(enum.Enum):
    """Why a procedure request cannot run."""

    UNKNOWN_PROCEDURE = "unknown procedure"
    """No procedure of that name is registered."""
    UNKNOWN_PARAMETER = "unknown parameter"
    """A parameter the procedure does not take."""
    BAD_VALUE = "bad value"
    """The procedure's factory refuses a value (a parameter or the dwell)."""
    TABLE_LIMITS = "table limits"
    """The preview walk breaks the table's limits (axes, angles, rates)."""


@dataclass(frozen=True)
class Refusal:
    """A procedure request that cannot run: what refuses it and why.

    :ivar kind: which check refuses it.
    :ivar procedure: the requested name.
    :ivar message: one line naming what and why (the error text the interfaces show).
    :ivar preview: the walk that found the problems (``TABLE_LIMITS`` only), else ``None``.
    """

    kind: RefusalKind
    procedure: str
    message: str
    preview: Preview | None = None


@dataclass(frozen=True)
class Admitted:
    """A procedure request that can run: the built procedure and its walk on the table."""

    procedure: Procedure
    preview: Preview


class ProcedureRefused(ValueError):
    """A :class:`Refusal` raised; ``str()`` is its message."""

    def __init__(self, refusal: Refusal) -> None:
        super().__init__(refusal.message)
        self.refusal = refusal


def _factory(name: str) -> Callable[..., Procedure] | Refusal:
    factory = PROCEDURES.get(name)
    if factory is None:
        known = ", ".join(sorted(PROCEDURES))
        return Refusal(RefusalKind.UNKNOWN_PROCEDURE, name, f"unknown procedure {name!r}; known: {known}")
    return factory


def accepted_parameters(factory: Callable[..., Procedure]) -> set[str]:
    """The keywords a procedure factory takes besides ``dwell_s`` (its own parameters)."""
    return set(inspect.signature(factory).parameters) - {"dwell_s"}


def _unknown_parameters(
    name: str, factory: Callable[..., Procedure], parameters: Mapping[str, object]
) -> Refusal | None:
    accepted = accepted_parameters(factory)
    unknown = sorted(set(parameters) - accepted)
    if not unknown:
        return None
    return Refusal(
        RefusalKind.UNKNOWN_PARAMETER,
        name,
        f"procedure {name!r} takes no parameter {', '.join(unknown)}; "
        f"it takes: {', '.join(sorted(accepted)) or 'none'}",
    )


def build_procedure(name: str, dwell_s: float | None = None, **parameters: object) -> Procedure:
    """Build a registered procedure (no table check: :func:`check_procedure` adds it).

    :raises ProcedureRefused: unknown name (the message lists the known ones), or a parameter
        the procedure does not take (named, with the ones it takes).
    :raises ValueError: a value the procedure's factory refuses.
    """
    factory = _factory(name)
    if isinstance(factory, Refusal):
        raise ProcedureRefused(factory)
    refusal = _unknown_parameters(name, factory, parameters)
    if refusal is not None:
        raise ProcedureRefused(refusal)
    return factory(dwell_s=dwell_s, **parameters)


def check_procedure(
    name: str,
    limits: TableLimits,
    *,
    dwell_s: float | None = None,
    parameters: Mapping[str, object] | None = None,
) -> Admitted | Refusal:
    """Build procedure ``name`` with ``dwell_s`` (s; ``None``: its noise window chooses) and
    ``parameters`` (its factory's keywords) and walk it against ``limits``
    (:func:`~bench.procedures.preview.preview`).

    :returns: :class:`Admitted` (procedure and preview), or the first :class:`Refusal` in the
        order name, parameter names, values, table limits.
    """
    factory = _factory(name)
    if isinstance(factory, Refusal):
        return factory
    kw = dict(parameters or {})
    refusal = _unknown_parameters(name, factory, kw)
    if refusal is not None:
        return refusal
    try:
        proc = factory(dwell_s=dwell_s, **kw)
    except ValueError as exc:
        return Refusal(RefusalKind.BAD_VALUE, name, str(exc))
    pv = preview(proc, limits)
    if not pv.ok:
        return Refusal(RefusalKind.TABLE_LIMITS, name, f"{name}: " + "; ".join(pv.problems), pv)
    return Admitted(proc, pv)


def admit_procedure(
    name: str,
    limits: TableLimits,
    *,
    dwell_s: float | None = None,
    parameters: Mapping[str, object] | None = None,
) -> Admitted:
    """:func:`check_procedure`, raising its refusal.

    :raises ProcedureRefused: the request's :class:`Refusal` (a ``ValueError``).
    """
    checked = check_procedure(name, limits, dwell_s=dwell_s, parameters=parameters)
    if isinstance(checked, Refusal):
        raise ProcedureRefused(checked)
    return checked
