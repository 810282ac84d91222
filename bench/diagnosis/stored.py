"""A run's diagnosis as the program reads it back: the typed form of the parts of the stored
``calbench diagnose --json`` object (``docs/cli-contract.md``) that findings rows,
certificates and run views use.

A fresh diagnosis gives it by :meth:`StoredDiagnosis.of`; a diagnosis stored as JSON (a run's
``run.diagnosis`` column) is parsed once, where it leaves the database, by
:meth:`StoredDiagnosis.from_contract`, which names the first missing or ill-typed key (its
dotted path, e.g. ``findings[0].summary``). Keys beyond the ones read are ignored.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from bench.diagnosis.result import Diagnosis, Finding
from bench.fitted_model import ContractError


@dataclass(frozen=True)
class StoredFinding:
    """One entry of ``findings``: an effect the recording supports.

    :param effect: catalogue id. :param summary: one sentence with the size of the effect.
    :param parameters: contract parameter name -> value (free-form JSON, lists per channel).
    :param sigma: the same shapes, one sigma.
    :param delta_bic: BIC change when the effect entered (negative); ``None`` when not stated.
    :param residual_rms_after: RMS of the residuals once it is in the model (channel units);
        ``None`` when not stated.
    """

    effect: str
    summary: str
    parameters: dict[str, Any]
    sigma: dict[str, Any]
    delta_bic: float | None
    residual_rms_after: float | None

    @classmethod
    def of(cls, finding: Finding) -> StoredFinding:
        """The parts of a fresh finding that are stored (``Finding.to_contract``)."""
        return cls(
            finding.effect,
            finding.summary,
            finding.parameters,
            finding.sigma,
            float(finding.delta_bic),
            float(finding.residual_rms_after),
        )


@dataclass(frozen=True)
class StoredDiagnosis:
    """A run's diagnosis as stored: its findings, in the order they entered the model."""

    findings: tuple[StoredFinding, ...]

    @classmethod
    def of(cls, diagnosis: Diagnosis) -> StoredDiagnosis:
        """The stored form of a fresh diagnosis (what :meth:`from_contract` reads from its
        ``to_contract()``)."""
        return cls(tuple(StoredFinding.of(f) for f in diagnosis.findings))

    @classmethod
    def from_contract(cls, contract: object, where: str = "diagnosis") -> StoredDiagnosis:
        """Parse a stored ``diagnose --json`` object.

        Each finding needs ``effect``, ``summary`` (strings), ``parameters``, ``sigma``
        (objects) and ``delta_bic`` (a number or null); ``residual_rms_after`` may be absent.

        :param where: what the object is, for the message (e.g. ``"run R-1: stored diagnosis"``).
        :raises ContractError: a key is missing or ill-typed; the message names ``where`` and the
            key's dotted path.
        """
        if not isinstance(contract, Mapping):
            raise ContractError(f"{where}: the diagnosis must be an object, got {_kind(contract)}")
        if "findings" not in contract:
            raise ContractError(f"{where}: key 'findings' is missing")
        findings = contract["findings"]
        if not isinstance(findings, list):
            raise ContractError(f"{where}: key 'findings' must be a list, got {_kind(findings)}")
        return cls(tuple(_finding(f, where, f"findings[{i}]") for i, f in enumerate(findings)))


def _kind(value: object) -> str:
    return f"{type(value).__name__} {value!r}"[:80]


def _finding(value: object, where: str, path: str) -> StoredFinding:
    if not isinstance(value, Mapping):
        raise ContractError(f"{where}: key {path!r} must be an object, got {_kind(value)}")

    def key(name: str) -> Any:
        if name not in value:
            raise ContractError(f"{where}: key '{path}.{name}' is missing")
        return value[name]

    def typed(name: str, kind: type, what: str) -> Any:
        v = key(name)
        if not isinstance(v, kind):
            raise ContractError(f"{where}: key '{path}.{name}' must be {what}, got {_kind(v)}")
        return v

    def number(name: str, v: object) -> float | None:
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ContractError(f"{where}: key '{path}.{name}' must be a number or null, got {_kind(v)}")
        return float(v)

    return StoredFinding(
        effect=typed("effect", str, "a string"),
        summary=typed("summary", str, "a string"),
        parameters=dict(typed("parameters", dict, "an object")),
        sigma=dict(typed("sigma", dict, "an object")),
        delta_bic=number("delta_bic", key("delta_bic")),
        residual_rms_after=number("residual_rms_after", value.get("residual_rms_after")),
    )
