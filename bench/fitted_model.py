"""The fitted first-order model of a run as the program passes it around: the typed form of
the ``calbench calibrate --json`` object (``docs/cli-contract.md``).

A fresh fit gives it by :meth:`bench.calibration.CalibrationResult.fitted_model`; a fit stored
as JSON (a run's ``fit_model`` row, an uploaded contract) is parsed once, where it leaves the
database, by :meth:`FittedModel.from_contract`, which names the first missing or ill-typed key.
Limits, certificates, exports and plots read the typed object, never the JSON by string key.

Model (per channel, first order): raw = b + K·f, b (3,) in the channel unit, K (3, 3) in the
channel unit per m/s², f the specific force in m/s²; the ``*_sigma`` are one-sigma (Type A)
uncertainties of the same shapes. The |g| check: e_w = |K⁻¹(ȳ_w − b)| − g_local over the
windows, its mean and standard deviation (m/s²).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from bench.fit_kind import DYNAMIC_BATCH, FitKind, stated_kind

FloatArray = npt.NDArray[np.float64]

__all__ = ["DYNAMIC_BATCH", "ContractError", "FittedModel", "GCheckSummary", "NominalReference"]

BIAS_REFERENCES = ("run_mean", "long_run")
"""The values of the contract's ``bias_reference`` (``bench.estimation.dynamic_batch.BiasReference``)."""


class ContractError(ValueError):
    """A stored ``calibrate --json`` object lacks a key or holds a value of the wrong type;
    the message names where it came from and the key's dotted path."""


@dataclass(frozen=True)
class NominalReference:
    """The nominal model a |g| check before adjustment was formed with (a unit's registration).

    :param scale: nominal scale (channel unit per m/s²). :param bias: nominal zero-g output
        (channel unit). :param source: where the values came from, e.g. ``"unit registration"``.
    """

    scale: float
    bias: float
    source: str


@dataclass(frozen=True)
class GCheckSummary:
    """The |g| check's statistics over the windows: mean and standard deviation of
    e_w = |f̂_w| − g_local (m/s²), and the nominal model when formed without the fit."""

    mean_error_m_s2: float
    std_m_s2: float
    nominal: NominalReference | None = None

    def to_contract(self) -> dict[str, Any]:
        """``{"mean_error_m_s2", "std_m_s2"}`` and ``"nominal": {"scale", "bias", "source"}`` when known."""
        out: dict[str, Any] = {"mean_error_m_s2": self.mean_error_m_s2, "std_m_s2": self.std_m_s2}
        if self.nominal is not None:
            n = self.nominal
            out["nominal"] = {"scale": n.scale, "bias": n.bias, "source": n.source}
        return out


@dataclass(frozen=True)
class FittedModel:
    """One fit of a recording, as stated by ``calibrate --json``.

    :param unit_serial: the unit's serial (``unit``; may be empty).
    :param channel_unit: the unit of the raw outputs.
    :param procedure: the procedure the recording followed.
    :param bias: (3,) b, channel units. :param bias_sigma: (3,) one sigma.
    :param K: (3, 3) ``scale_matrix``, channel unit per m/s². :param K_sigma: (3, 3) one sigma.
    :param terms: model terms fitted.
    :param residual_rms: RMS of the residuals (channel units), ``None`` when not stated.
    :param g_after: the |g| check after correction by this fit.
    :param g_before: the |g| check with the nominal scale, ``None`` when no nominal was known.
    :param extra: fitted values of the terms beyond b and K (effect id -> parameter -> value;
        free-form JSON as the contract gives it).
    :param method: the contract's ``method`` (:data:`DYNAMIC_BATCH` for a moving-table fit),
        ``None`` for a static or orientation-free fit.
    :param bias_reference: what ``bias_sigma`` describes: ``"long_run"`` (the unit's long-run
        bias, a wander's average over the run included) or ``"run_mean"`` (the run's mean bias
        only); ``None`` for a stored fit from before the key existed.
    """

    unit_serial: str
    channel_unit: str
    procedure: str
    bias: FloatArray
    bias_sigma: FloatArray
    K: FloatArray
    K_sigma: FloatArray
    terms: tuple[str, ...]
    residual_rms: float | None
    g_after: GCheckSummary
    g_before: GCheckSummary | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    method: str | None = None
    bias_reference: str | None = None

    @property
    def kind(self) -> FitKind:
        """The kind of fit its ``method`` and ``terms`` state (:func:`bench.fit_kind.stated_kind`)."""
        return stated_kind(self.method, self.terms)

    @classmethod
    def from_contract(cls, contract: object, where: str = "calibration") -> FittedModel:
        """Parse a stored ``calibrate --json`` object (keys beyond the ones read are ignored).

        :param where: what the object is, for the message (e.g. ``"run R-1: stored fit"``).
        :raises ContractError: a key is missing or ill-typed; the message names ``where`` and
            the key's dotted path (``g_check.after.mean_error_m_s2``).
        """
        c = _object(contract, where, "")
        g = _object(_key(c, "g_check", where, ""), where, "g_check")
        before = g.get("before")
        extra = c.get("extra", {})
        if not isinstance(extra, dict):
            raise ContractError(f"{where}: key 'extra' must be an object, got {_kind(extra)}")
        method = c.get("method")
        if method is not None and not isinstance(method, str):
            raise ContractError(f"{where}: key 'method' must be a string, got {_kind(method)}")
        reference = c.get("bias_reference")
        if reference is not None and reference not in BIAS_REFERENCES:
            raise ContractError(
                f"{where}: key 'bias_reference' must be one of {', '.join(BIAS_REFERENCES)}, "
                f"got {_kind(reference)}"
            )
        terms = _key(c, "terms", where, "")
        if not (isinstance(terms, list) and all(isinstance(t, str) for t in terms)):
            raise ContractError(f"{where}: key 'terms' must be a list of strings, got {_kind(terms)}")
        rms = c.get("residual_rms")
        return cls(
            unit_serial=_string(c, "unit", where, ""),
            channel_unit=_string(c, "channel_unit", where, ""),
            procedure=_string(c, "procedure", where, ""),
            bias=_array(c, "bias", (3,), where),
            bias_sigma=_array(c, "bias_sigma", (3,), where),
            K=_array(c, "scale_matrix", (3, 3), where),
            K_sigma=_array(c, "scale_matrix_sigma", (3, 3), where),
            terms=tuple(terms),
            residual_rms=None if rms is None else _number(rms, where, "residual_rms"),
            g_after=_g_summary(_key(g, "after", where, "g_check"), where, "g_check.after"),
            g_before=None if before is None else _g_summary(before, where, "g_check.before"),
            extra=extra,
            method=method,
            bias_reference=reference,
        )


def _kind(value: object) -> str:
    return f"{type(value).__name__} {value!r}"[:80]


def _path(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def _object(value: object, where: str, path: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        what = f"key {path!r}" if path else "the fit"
        raise ContractError(f"{where}: {what} must be an object, got {_kind(value)}")
    return value


def _key(obj: Mapping[str, Any], key: str, where: str, prefix: str) -> Any:
    if key not in obj:
        raise ContractError(f"{where}: key {_path(prefix, key)!r} is missing")
    return obj[key]


def _string(obj: Mapping[str, Any], key: str, where: str, prefix: str) -> str:
    value = _key(obj, key, where, prefix)
    if not isinstance(value, str):
        raise ContractError(f"{where}: key {_path(prefix, key)!r} must be a string, got {_kind(value)}")
    return value


def _number(value: object, where: str, path: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ContractError(f"{where}: key {path!r} must be a number, got {_kind(value)}")
    return float(value)


def _array(obj: Mapping[str, Any], key: str, shape: tuple[int, ...], where: str) -> FloatArray:
    value = _key(obj, key, where, "")
    rows = value if len(shape) == 2 and isinstance(value, list) else [value]
    ok = isinstance(value, list) and len(value) == shape[0]
    if ok and len(shape) == 2:
        ok = all(isinstance(r, list) and len(r) == shape[1] for r in rows)
    if ok:
        ok = all(isinstance(x, int | float) and not isinstance(x, bool) for r in rows for x in r)
    if not ok:
        dims = " x ".join(str(n) for n in shape)
        raise ContractError(f"{where}: key {key!r} must be {dims} numbers, got {_kind(value)}")
    return np.asarray(value, dtype=float)


def _g_summary(value: object, where: str, path: str) -> GCheckSummary:
    g = _object(value, where, path)
    nominal = g.get("nominal")
    ref = None
    if nominal is not None:
        n = _object(nominal, where, f"{path}.nominal")
        ref = NominalReference(
            _number(_key(n, "scale", where, f"{path}.nominal"), where, f"{path}.nominal.scale"),
            _number(_key(n, "bias", where, f"{path}.nominal"), where, f"{path}.nominal.bias"),
            _string(n, "source", where, f"{path}.nominal"),
        )
    return GCheckSummary(
        _number(_key(g, "mean_error_m_s2", where, path), where, f"{path}.mean_error_m_s2"),
        _number(_key(g, "std_m_s2", where, path), where, f"{path}.std_m_s2"),
        ref,
    )
