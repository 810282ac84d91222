"""What a certificate is built from: the run (:class:`RunFacts`), the unit (:class:`UnitFacts`),
the stored fit, the budget and the limit checks (:class:`CertificateInputs`), and who issues it
(:class:`Laboratory`)."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any

from bench.diagnosis.stored import StoredDiagnosis
from bench.fitted_model import FittedModel
from bench.limit_check import LimitCheck
from bench.run_state import RunState
from station.certificates.budget import CertificateBudget


@dataclass(frozen=True)
class ActionFact:
    """One action on the run as its audit trail stores it (``db.models.RunAudit``).

    :param at: when (UTC). :param actor: the operator's name, ``agent`` or ``system``.
    :param action: ``start``, ``pause``, ``continue``, ``abort``, ``resume`` or ``state``.
    :param state: the new state of a ``state`` action, else ``None``.
    :param detail: the reason or request. :param window_index: the window it concerns, if any.
    """

    at: dt.datetime
    actor: str
    action: str
    state: RunState | None = None
    detail: str = ""
    window_index: int | None = None


@dataclass(frozen=True)
class RunFacts:
    """What the certificate states about the run.

    :param id: the run's id. :param procedure: its procedure.
    :param started_at: :param finished_at: wall-clock start and end (UTC).
    :param parameters: the procedure's parameters as stored (free-form JSON).
    :param bench: the bench's name.
    :param sample_gaps: the run's gap records as stored (``bench.records.GapRecord`` as dicts);
        empty: none.
    :param bench_config: the bench file's identity (``bench.bench_config.BenchConfig.identity``).
    :param actions: every action on the run, oldest first (its audit trail); empty: none stored.
    """

    id: str | None = None
    procedure: str = ""
    started_at: dt.datetime | None = None
    finished_at: dt.datetime | None = None
    parameters: dict[str, Any] = field(default_factory=dict)
    bench: str | None = None
    sample_gaps: list[dict[str, Any]] = field(default_factory=list)
    bench_config: dict[str, Any] | None = None
    actions: tuple[ActionFact, ...] = ()


@dataclass(frozen=True)
class UnitFacts:
    """What the certificate states about the item and its customer (the unit's registration);
    ``None`` where not given.

    :param nominal_scale: channel unit per m/s². :param nominal_bias: zero-g output, channel unit.
    """

    serial: str
    model: str | None = None
    channel_unit: str | None = None
    description: str | None = None
    condition: str | None = None
    customer_name: str | None = None
    customer_address: str | None = None
    received_on: dt.date | None = None
    nominal_scale: float | None = None
    nominal_bias: float | None = None


@dataclass(frozen=True)
class CertificateInputs:
    """What a certificate is built from.

    :param run: the run. :param unit: the unit under calibration.
    :param calibration: the run's stored fit.
    :param g_local_m_s2: local gravity used (m/s²), ``None`` when unknown.
    :param temp_c: (min, mean, max) sensor temperature over the windows (°C), or ``None``.
    :param table: table description (axes, mount, lever arm) from the sidecar, or ``None``.
    :param diagnosis: the run's diagnosis (its findings), or ``None`` when not run.
    :param diagnosis_note: why there is no diagnosis, when there is none.
    :param simulated: the bench was simulated (results are then not traceable).
    :param deviations: additions to / deviations from the method (7.8.2.1 n).
    :param budget: the uncertainty budget (``station.certificates.budget.certificate_budget``), or
        ``None`` (Type A only, k = 2).
    :param budget_note: why there is no budget, when there is none.
    :param limit_checks: the run's stored limit checks (with U and the acceptance interval of
        the decision rule); empty: no limits applied.
    :param outcome: the run's stored outcome (``PASS``/``FAIL``), which the conformity
        statement must agree with.
    :param limits_model: the unit model whose limits judged the run.
    :param limits_note: why no limits judged the run (stated in place of a conformity statement).
    :param g_check_n: windows (or 1 s blocks) of the |g| check, for the U of its mean; ``None``
        when not known (U not stated).
    """

    run: RunFacts
    unit: UnitFacts
    calibration: FittedModel
    g_local_m_s2: float | None
    temp_c: tuple[float, float, float] | None = None
    table: dict[str, Any] | None = None
    diagnosis: StoredDiagnosis | None = None
    diagnosis_note: str = ""
    simulated: bool = False
    deviations: list[str] = field(default_factory=list)
    budget: CertificateBudget | None = None
    budget_note: str = ""
    limit_checks: tuple[LimitCheck, ...] = ()
    outcome: str | None = None
    limits_model: str | None = None
    limits_note: str = ""
    g_check_n: int | None = None


@dataclass(frozen=True)
class Laboratory:
    """Who issues: name, address, location of the work, who authorises (7.8.2.1 b, c, o), the
    customer of units registered without one (an in-house laboratory's own department), the
    bench's reference standards with their calibration status (7.8.4.1 c) and the ambient
    conditions (7.8.4.1 b)."""

    name: str
    address: str
    location: str
    authorized_by: str
    default_customer_name: str = ""
    default_customer_address: str = ""
    reference_equipment: tuple[str, ...] = ()
    ambient_conditions: str = ""
