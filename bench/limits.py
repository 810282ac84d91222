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
  poses, ``g_check.after.mean_error_m_s2`` of the contract) within ``±`` this.

Decision rule: simple acceptance (ILAC-G8:09/2019 §4.2.1, no guard band) — a value passes
when it lies inside its interval; the fit's uncertainty is reported beside the verdict, not
subtracted from the limits.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.records import LimitCheck, Outcome

DEFAULT_LIMITS_FILE = Path(__file__).with_name("data") / "unit_limits.json"
FORMAT = "calbench-unit-limits/1"
AXES = "xyz"
_KEYS = ("channel_unit", "nominal_bias", "bias_tolerance", "nominal_scale", "scale_tolerance_rel",
         "cross_axis_max", "g_error_after_max_m_s2")


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

    def check(self, value: float) -> LimitCheck:
        """The check of ``value`` (NaN never passes)."""
        ok = math.isfinite(value) and (self.low is None or value >= self.low) and (
            self.high is None or value <= self.high)
        return LimitCheck(self.name, self.unit, float(value), self.low, self.high, bool(ok))


@dataclass(frozen=True)
class UnitLimits:
    """The limits of one unit model.

    :param model: model name. :param channel_unit: the unit of the outputs they apply to.
    :param limits: bias_x..z, scale_x..z, cross_axis_xy..zy, g_error_after.
    """

    model: str
    channel_unit: str
    limits: tuple[Limit, ...]

    @classmethod
    def from_spec(cls, model: str, spec: Mapping[str, Any], where: str = "limits") -> UnitLimits:
        """Build from one model entry of the JSON file; errors name ``where`` and the key."""
        missing = [k for k in _KEYS if k not in spec]
        if missing:
            raise ValueError(f"{where}: model {model!r} lacks {', '.join(missing)}")
        unit = str(spec["channel_unit"])
        nb, ns = _vec3(spec, "nominal_bias", model, where), _vec3(spec, "nominal_scale", model, where)
        tol_b, tol_s, tol_c, tol_g = (_positive(spec, k, model, where) for k in (
            "bias_tolerance", "scale_tolerance_rel", "cross_axis_max", "g_error_after_max_m_s2"))
        out = [Limit(f"bias_{a}", unit, nb[i] - tol_b, nb[i] + tol_b) for i, a in enumerate(AXES)]
        out += [Limit(f"scale_{a}", f"{unit}/(m/s2)", ns[i] * (1 - tol_s), ns[i] * (1 + tol_s))
                for i, a in enumerate(AXES)]
        out += [Limit(f"cross_axis_{AXES[i]}{AXES[j]}", "1", -tol_c, tol_c)
                for i in range(3) for j in range(3) if i != j]
        out.append(Limit("g_error_after", "m/s2", -tol_g, tol_g))
        return cls(model, unit, tuple(out))


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


def evaluate(contract: Mapping[str, Any], limits: UnitLimits) -> tuple[LimitCheck, ...]:
    """Check a ``calibrate --json`` object against a model's limits (order of ``limits.limits``).

    :raises ValueError: the channel units differ, or the contract lacks a checked value.
    """
    if contract.get("channel_unit") != limits.channel_unit:
        raise ValueError(f"limits of {limits.model} are for {limits.channel_unit} outputs, the fit is in "
                         f"{contract.get('channel_unit')!r}")
    try:
        b = [float(v) for v in contract["bias"]]
        K = [[float(v) for v in row] for row in contract["scale_matrix"]]
        g_after = float(contract["g_check"]["after"]["mean_error_m_s2"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"the fit lacks a value the limits check: {exc!r}") from exc
    values = {f"bias_{a}": b[i] for i, a in enumerate(AXES)}
    values.update({f"scale_{a}": K[i][i] for i, a in enumerate(AXES)})
    values.update({f"cross_axis_{AXES[i]}{AXES[j]}": K[i][j] / K[i][i] for i in range(3) for j in range(3)
                   if i != j})
    values["g_error_after"] = g_after
    return tuple(lim.check(values[lim.name]) for lim in limits.limits)


def verdict(contract: Mapping[str, Any], limits: UnitLimits | None) -> tuple[Outcome, tuple[LimitCheck, ...]]:
    """PASS when every check passes (or no limits apply), else FAIL; with the checks."""
    if limits is None:
        return Outcome.PASS, ()
    checks = evaluate(contract, limits)
    return (Outcome.PASS if all(c.passed for c in checks) else Outcome.FAIL), checks


def describe(check: LimitCheck) -> str:
    """``"bias_x = 1.62 V, limits [1.45, 1.55] V"``."""
    lo = "-inf" if check.low is None else f"{check.low:.6g}"
    hi = "inf" if check.high is None else f"{check.high:.6g}"
    return f"{check.name} = {check.value:.6g} {check.unit}, limits [{lo}, {hi}] {check.unit}"
