"""One fitted value of a run checked against its tolerance, as the run's record carries it and
the database stores it (``dataclasses.asdict``); read back by :meth:`LimitCheck.from_stored`,
which names a missing or ill-typed key. The limits and the verdict are in :mod:`bench.limits`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class LimitCheck:
    """One fitted value checked against its tolerance.

    :param name: what was checked, e.g. ``"bias_x"``.
    :param unit: unit of ``value``, ``low``, ``high``.
    :param value: the fitted value.
    :param low: lower limit (``None``: unbounded).
    :param high: upper limit (``None``: unbounded).
    :param passed: the decision rule's verdict: ``acceptance_low <= value <= acceptance_high``.
    :param expanded_uncertainty: U of ``value`` (k ≈ 2, the certificate's), ``None`` when not known.
    :param acceptance_low: lower acceptance limit: ``low`` (simple acceptance) or ``low + U``
        (guarded acceptance, guard band w = U); ``None``: unbounded.
    :param acceptance_high: upper acceptance limit: ``high`` or ``high - U``.
    :param rule: the decision rule (``bench.limits.DECISION_RULES`` key).
    """

    name: str
    unit: str
    value: float
    low: float | None
    high: float | None
    passed: bool
    expanded_uncertainty: float | None = None
    acceptance_low: float | None = None
    acceptance_high: float | None = None
    rule: str = "simple-acceptance"

    @classmethod
    def from_stored(cls, obj: object, where: str) -> LimitCheck:
        """Parse a check as stored (the object ``dataclasses.asdict`` wrote). A check stored
        before it carried U and an acceptance interval has none and its tolerance interval.

        :raises ValueError: not an object, or a key missing or ill-typed (named with ``where``).
        """
        if not isinstance(obj, Mapping):
            raise ValueError(f"{where}: must be an object, got {type(obj).__name__}")

        def text(key: str, default: str | None = None) -> str:
            if key not in obj and default is None:
                raise ValueError(f"{where}: key {key!r} is missing")
            value = obj.get(key, default)
            if not isinstance(value, str):
                raise ValueError(f"{where}: key {key!r} must be a string, got {value!r}")
            return value

        def number(key: str, default: float | None = None, *, optional: bool = True) -> float | None:
            if key not in obj and not optional:
                raise ValueError(f"{where}: key {key!r} is missing")
            value = obj.get(key, default)
            if value is None and optional:
                return None
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{where}: key {key!r} must be a number, got {value!r}")
            return float(value)

        if "passed" not in obj:
            raise ValueError(f"{where}: key 'passed' is missing")
        passed = obj["passed"]
        if not isinstance(passed, bool):
            raise ValueError(f"{where}: key 'passed' must be true or false, got {passed!r}")
        value = number("value", optional=False)
        assert value is not None
        low, high = number("low"), number("high")
        return cls(
            text("name"),
            text("unit"),
            value,
            low,
            high,
            passed,
            number("expanded_uncertainty"),
            number("acceptance_low", low),
            number("acceptance_high", high),
            text("rule", "simple-acceptance"),
        )
