"""Acceptance limits of a unit model and the PASS / FAIL verdict of a calibration.

A unit model's limits (from a small JSON file, ``bench/data/unit_limits.json`` by default,
format ``calbench-unit-limits/1``) give, per model:

* ``nominal_bias`` (3,) and ``bias_tolerance`` (channel units): each fitted bias b_i must lie
  in ``nominal_bias_i ± bias_tolerance``;
* ``nominal_scale`` (3,) (channel units per m/s²) and ``scale_tolerance_rel``: each diagonal
  K_ii in ``nominal_scale_i · (1 ± scale_tolerance_rel)``;
* ``cross_axis_max``: each off-diagonal ratio K_ij / K_ii (the sensitivity of channel i to
  axis j relative to its own, ≈ the misalignment angle in rad) within ``±cross_axis_max``;
* ``g_error_after_max_m_s2``: the |g| check after correction (mean of |f̂| − g over the
  poses, ``g_check.after.mean_error_m_s2`` of ``calibrate --json``) within ``±`` this.

Decision rule (ILAC-G8:09/2019 §4.2), chosen per model by the optional key ``decision_rule``:

* ``"simple-acceptance"`` (the default; §4.2.1, guard band w = 0): a value passes when it lies
  inside its tolerance interval; its expanded uncertainty U is reported beside the verdict;
* ``"guarded-acceptance"`` (§4.2.2, guard band w = U): the acceptance interval is the tolerance
  interval shrunk by U at each bound, [low + U, high − U]; a value passes only inside it, so
  the probability of false acceptance is below about 2.5 %. Needs U of every checked value.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.fitted_model import FittedModel
from bench.limit_check import LimitCheck
from bench.run_state import Outcome

DEFAULT_LIMITS_FILE = Path(__file__).with_name("data") / "unit_limits.json"
FORMAT = "calbench-unit-limits/1"
AXES = "xyz"
DECISION_RULES = {
    "simple-acceptance": "simple acceptance (ILAC-G8:09/2019 4.2.1, guard band w = 0): a value conforms when "
    "it lies inside its tolerance interval; the expanded uncertainty U is stated but not subtracted",
    "guarded-acceptance": "guarded acceptance (ILAC-G8:09/2019 4.2.2, binary statement with guard band "
    "w = U): a value conforms when it lies inside its tolerance interval shrunk by its expanded "
    "uncertainty U at each bound (probability of false acceptance below about 2.5 %)",
}
"""Each decision rule and the sentence a certificate states for it."""
_KEYS = (
    "channel_unit",
    "nominal_bias",
    "bias_tolerance",
    "nominal_scale",
    "scale_tolerance_rel",
    "cross_axis_max",
    "g_error_after_max_m_s2",
)


@dataclass(frozen=True)
class Limit:
    """One quantity's allowed interval.

    :param name: e.g. ``"bias_x"``. :param unit: unit of the bounds.
    :param low: lower bound (``None``: unbounded). :param high: upper bound (``None``: unbounded).
    """

    name: str
    unit: str
    low: float | None
    high: float | None

    def check(
        self, value: float, expanded_uncertainty: float | None = None, rule: str = "simple-acceptance"
    ) -> LimitCheck:
        """The check of ``value`` under the decision ``rule`` (NaN never passes).

        :param expanded_uncertainty: U of ``value`` (same unit); required by guarded acceptance.
        :raises ValueError: unknown rule, or guarded acceptance without a finite U >= 0.
        """
        if rule not in DECISION_RULES:
            raise ValueError(
                f"limit {self.name}: unknown decision rule {rule!r} (known: {', '.join(DECISION_RULES)})"
            )
        U = None if expanded_uncertainty is None else float(expanded_uncertainty)
        w = 0.0
        if rule == "guarded-acceptance":
            if U is None or not (math.isfinite(U) and U >= 0):
                raise ValueError(
                    f"limit {self.name}: guarded acceptance needs the expanded uncertainty, got {U!r}"
                )
            w = U
        lo = None if self.low is None else self.low + w
        hi = None if self.high is None else self.high - w
        ok = math.isfinite(value) and (lo is None or value >= lo) and (hi is None or value <= hi)
        return LimitCheck(self.name, self.unit, float(value), self.low, self.high, bool(ok), U, lo, hi, rule)


@dataclass(frozen=True)
class UnitLimits:
    """The limits of one unit model.

    :param model: model name. :param channel_unit: the unit of the outputs they apply to.
    :param limits: bias_x..z, scale_x..z, cross_axis_xy..zy, g_error_after.
    :param decision_rule: a :data:`DECISION_RULES` key.
    """

    model: str
    channel_unit: str
    limits: tuple[Limit, ...]
    decision_rule: str = "simple-acceptance"

    @classmethod
    def from_spec(cls, model: str, spec: Mapping[str, Any], where: str = "limits") -> UnitLimits:
        """Build from one model entry of the JSON file; errors name ``where`` and the key."""
        missing = [k for k in _KEYS if k not in spec]
        if missing:
            raise ValueError(f"{where}: model {model!r} lacks {', '.join(missing)}")
        unit = str(spec["channel_unit"])
        nb, ns = _vec3(spec, "nominal_bias", model, where), _vec3(spec, "nominal_scale", model, where)
        tol_b, tol_s, tol_c, tol_g = (
            _positive(spec, k, model, where)
            for k in ("bias_tolerance", "scale_tolerance_rel", "cross_axis_max", "g_error_after_max_m_s2")
        )
        out = [Limit(f"bias_{a}", unit, nb[i] - tol_b, nb[i] + tol_b) for i, a in enumerate(AXES)]
        out += [
            Limit(f"scale_{a}", f"{unit}/(m/s2)", ns[i] * (1 - tol_s), ns[i] * (1 + tol_s))
            for i, a in enumerate(AXES)
        ]
        out += [
            Limit(f"cross_axis_{AXES[i]}{AXES[j]}", "1", -tol_c, tol_c)
            for i in range(3)
            for j in range(3)
            if i != j
        ]
        out.append(Limit("g_error_after", "m/s2", -tol_g, tol_g))
        rule = spec.get("decision_rule", "simple-acceptance")
        if rule not in DECISION_RULES:
            raise ValueError(
                f"{where}: model {model!r}: decision_rule must be one of {', '.join(DECISION_RULES)}, "
                f"got {rule!r}"
            )
        return cls(model, unit, tuple(out), str(rule))


def _vec3(spec: Mapping[str, Any], key: str, model: str, where: str) -> tuple[float, float, float]:
    v = spec[key]
    if not (isinstance(v, Sequence) and len(v) == 3 and all(_finite(x) for x in v)):
        raise ValueError(f"{where}: model {model!r}: {key} must be 3 finite numbers, got {v!r}")
    return (float(v[0]), float(v[1]), float(v[2]))


def _positive(spec: Mapping[str, Any], key: str, model: str, where: str) -> float:
    v = spec[key]
    if not (_finite(v) and float(v) > 0):
        raise ValueError(f"{where}: model {model!r}: {key} must be a finite number > 0, got {v!r}")
    return float(v)


def _finite(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def load_limits(path: str | Path | None = None) -> dict[str, UnitLimits]:
    """Every model of a limits file (default: the one shipped with calbench).

    :raises ValueError: unreadable, not JSON, another format, or a model entry missing or bad (named).
    """
    path = Path(path) if path is not None else DEFAULT_LIMITS_FILE
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON: {exc}") from exc
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the limits file: {exc.strerror or exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("models"), dict):
        raise ValueError(f"{path}: expected an object with format {FORMAT!r} and a 'models' object")
    return {name: UnitLimits.from_spec(name, spec, str(path)) for name, spec in doc["models"].items()}


@dataclass(frozen=True)
class LimitsChoice:
    """The limits that judge a unit, or why none do.

    :param limits: the model's limits; ``None``: no statement of conformity can be made.
    :param reason: one sentence saying why no limits apply (empty when they do).
    :param known_models: the models the limits file has, when the unit's is not among them.
    """

    limits: UnitLimits | None
    reason: str = ""
    known_models: tuple[str, ...] = ()

    @property
    def note(self) -> str:
        """What a run judged by no limits shows in place of PASS or FAIL:
        ``"no conformity statement: no limits are configured for model ADXL335"``; empty when
        limits apply."""
        if self.limits is not None:
            return ""
        return f"no conformity statement: {self.reason or 'no limits apply'}"


def choose_limits(
    table: Mapping[str, UnitLimits], model: str | None, channel_unit: str | None, default_model: str = ""
) -> LimitsChoice:
    """The limits of a unit registered as ``model`` with ``channel_unit`` outputs.

    A unit is judged only against its own model's limits: a model the limits file lacks gets no
    limits (never another model's). ``default_model`` judges only a unit whose registration names
    no model. Limits for other outputs than ``channel_unit`` do not apply (``None``: not known yet).
    """
    name = (model or "").strip()
    if name:
        if name not in table:
            return LimitsChoice(None, f"no limits are configured for model {name}", tuple(sorted(table)))
        chosen = table[name]
    elif default_model and default_model in table:
        chosen = table[default_model]
    elif default_model:
        return LimitsChoice(
            None,
            f"the unit's registration names no model and the default limits model {default_model} "
            "is not in the limits file",
        )
    else:
        return LimitsChoice(None, "the unit's registration names no model and no default limits model is set")
    if channel_unit is not None and chosen.channel_unit != channel_unit:
        return LimitsChoice(
            None,
            f"the limits of model {chosen.model} are for {chosen.channel_unit} outputs, "
            f"the unit's outputs are in {channel_unit}",
        )
    return LimitsChoice(chosen)


def checked_values(fit: FittedModel) -> dict[str, float]:
    """The values the limits check, by limit name: b_i, K_ii, K_ij / K_ii and the mean |g|
    error after correction (m/s²)."""
    b, K = fit.bias, fit.K
    values = {f"bias_{a}": float(b[i]) for i, a in enumerate(AXES)}
    values.update({f"scale_{a}": float(K[i, i]) for i, a in enumerate(AXES)})
    values.update(
        {
            f"cross_axis_{AXES[i]}{AXES[j]}": float(K[i, j] / K[i, i])
            for i in range(3)
            for j in range(3)
            if i != j
        }
    )
    values["g_error_after"] = fit.g_after.mean_error_m_s2
    return values


def evaluate(
    fit: FittedModel, limits: UnitLimits, uncertainties: Mapping[str, float] | None = None
) -> tuple[LimitCheck, ...]:
    """Check a fit against a model's limits (order of ``limits.limits``) under the model's
    decision rule.

    :param uncertainties: expanded uncertainty U of each checked value by limit name
        (:func:`checked_values` names); required by guarded acceptance, stated otherwise.
    :raises ValueError: the channel units differ, or guarded acceptance lacks a U.
    """
    if fit.channel_unit != limits.channel_unit:
        raise ValueError(
            f"limits of {limits.model} are for {limits.channel_unit} outputs, the fit is in "
            f"{fit.channel_unit!r}"
        )
    values = checked_values(fit)
    us = uncertainties or {}
    return tuple(lim.check(values[lim.name], us.get(lim.name), limits.decision_rule) for lim in limits.limits)


def verdict(
    fit: FittedModel, limits: UnitLimits | None, uncertainties: Mapping[str, float] | None = None
) -> tuple[Outcome | None, tuple[LimitCheck, ...]]:
    """PASS when every check passes, else FAIL; with the checks. ``None`` and no checks when no
    limits apply: a fit no limits judged has no verdict (no statement of conformity)."""
    if limits is None:
        return None, ()
    checks = evaluate(fit, limits, uncertainties)
    return (Outcome.PASS if all(c.passed for c in checks) else Outcome.FAIL), checks


def describe(check: LimitCheck) -> str:
    """``"bias_x = 1.62 V, limits [1.45, 1.55] V"`` (and the acceptance interval under a guard band)."""
    lo = "-inf" if check.low is None else f"{check.low:.6g}"
    hi = "inf" if check.high is None else f"{check.high:.6g}"
    text = f"{check.name} = {check.value:.6g} {check.unit}, limits [{lo}, {hi}] {check.unit}"
    if check.rule == "guarded-acceptance":
        alo = "-inf" if check.acceptance_low is None else f"{check.acceptance_low:.6g}"
        ahi = "inf" if check.acceptance_high is None else f"{check.acceptance_high:.6g}"
        text += f", acceptance [{alo}, {ahi}] (guard band U = {check.expanded_uncertainty:.2g})"
    return text
