"""The diagnosis as frozen data, and its ``calbench diagnose --json`` form (docs/cli-contract.md)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.regressors import Correlation


@dataclass(frozen=True)
class ModelSummary:
    """One model's agreement with the recording.

    :param terms: ``bias``, ``scale_matrix`` and the effect ids added.
    :param residual_rms: RMS of the window residuals (channel units).
    :param chi2_dof: χ² / (n − p) against the noise the recording shows.
    :param bic: −2 ℓ + k ln n (k: fitted parameters, noise parameters included).
    :param resid: (m, 3) window residuals (channel units).
    :param z: (m, 3) residuals over their noise sigma.
    """

    terms: tuple[str, ...]
    residual_rms: float
    chi2_dof: float
    bic: float
    resid: FloatArray
    z: FloatArray

    def to_contract(self) -> dict[str, Any]:
        """``{terms, residual_rms, chi2_dof, bic}``."""
        return {
            "terms": list(self.terms),
            "residual_rms": self.residual_rms,
            "chi2_dof": self.chi2_dof,
            "bic": self.bic,
        }


@dataclass(frozen=True)
class Finding:
    """An effect the recording supports, with its fitted parameters.

    :param effect: catalogue id; :param summary: one sentence with the size of the effect.
    :param parameters: contract parameter name -> value (lists); :param sigma: same shapes, one sigma.
    :param delta_bic: BIC change when the effect entered (negative).
    :param lr: likelihood-ratio statistic when it entered.
    :param residual_rms_after: RMS of the residuals once it is in the model.
    :param explanation: the physics, one sentence.
    :param confounded_with: effects that fit this recording equally well.
    """

    effect: str
    summary: str
    parameters: dict[str, Any]
    sigma: dict[str, Any]
    delta_bic: float
    lr: float
    residual_rms_after: float
    explanation: str
    confounded_with: tuple[str, ...] = ()

    def to_contract(self) -> dict[str, Any]:
        """One entry of ``findings``."""
        return {
            "effect": self.effect,
            "summary": self.summary,
            "parameters": self.parameters,
            "sigma": self.sigma,
            "delta_bic": self.delta_bic,
            "residual_rms_after": self.residual_rms_after,
        }


@dataclass(frozen=True)
class Discovery:
    """A term beyond the catalogue that the recording supports (``library``).

    :param channel: ``ax``, ``ay``, ``az`` (or ``all``); :param term: the contract's grammar.
    :param coefficient: channel units per unit of the term; :param sigma: its one sigma.
    :param unit: e.g. ``V per g^3``; :param delta_bic: BIC change when it entered.
    :param residual_rms_after: RMS of the window residuals once it is in.
    :param physics: the mechanism where the term has a known one, else a plain sentence.
    :param lr: its statistic when it entered; :param confounded_with: other terms (or
        catalogue effects) that fit this recording about as well.
    """

    channel: str
    term: str
    coefficient: float
    sigma: float
    unit: str
    delta_bic: float
    residual_rms_after: float
    physics: str
    lr: float = 0.0
    confounded_with: tuple[str, ...] = ()

    def to_contract(self) -> dict[str, Any]:
        """One entry of ``discovered``."""
        out: dict[str, Any] = {
            "channel": self.channel,
            "term": self.term,
            "coefficient": self.coefficient,
            "sigma": self.sigma,
            "unit": self.unit,
            "delta_bic": self.delta_bic,
            "residual_rms_after": self.residual_rms_after,
            "physics": self.physics,
        }
        if self.confounded_with:
            out["confounded_with"] = list(self.confounded_with)
        return out


@dataclass(frozen=True)
class Unexplained:
    """The final model still fails the recording's own noise.

    :param chi2_dof: the final model's χ²/dof; :param test: the test and its level.
    :param p_value: the test's p value; :param where: where the remaining mismatch is.
    :param correlates_with: regressors the remaining residual correlates with.
    :param channels: per channel, observed χ² over what the noise model expects.
    :param channel: the channel that carries the misfit alone, where a one-channel test names
        one (``channel_excess``), else ``None``.
    """

    chi2_dof: float
    test: str
    p_value: float
    where: str
    correlates_with: tuple[str, ...]
    channels: dict[str, float]
    channel: str | None = None

    def to_contract(self) -> dict[str, Any]:
        """The ``unexplained`` object (``channel`` only when one is named)."""
        out: dict[str, Any] = {
            "chi2_dof": self.chi2_dof,
            "test": self.test,
            "p_value": self.p_value,
            "where": self.where,
            "correlates_with": list(self.correlates_with),
            "channels": dict(self.channels),
        }
        if self.channel is not None:
            out["channel"] = self.channel
        return out


@dataclass(frozen=True)
class Diagnosis:
    """Everything ``diagnose`` concluded about one recording.

    :param channel_ratio: (3,) baseline χ²_i / (m − 4) per channel (1: explained to the noise).
    :param where: where the baseline mismatch is strongest.
    :param correlations: regressor correlations with the baseline residuals, strongest first.
    :param unobservable: effect id -> why this recording cannot show it.
    :param notes: further remarks (effects indistinguishable on this pose set, noise model).
    :param noise_text: the noise model the χ² and sigmas use.
    :param labels: window labels; :param mid_s: (m,) window times (s).
    :param bias: (3,) and :param K: (3, 3) of the final model (channel units, per m/s²).
    """

    unit: str
    channel_unit: str
    method: str
    baseline: ModelSummary
    final: ModelSummary
    findings: tuple[Finding, ...]
    channel_ratio: FloatArray
    where: str
    correlations: tuple[Correlation, ...]
    unobservable: dict[str, str]
    notes: tuple[str, ...]
    noise_text: str
    labels: tuple[str, ...]
    mid_s: FloatArray
    bias: FloatArray
    K: FloatArray
    source: str = ""
    discovered: tuple[Discovery, ...] = ()
    unexplained: Unexplained | None = None

    @property
    def fits(self) -> bool:
        """The final model explains the recording to its noise (no ``unexplained``)."""
        return self.unexplained is None

    def correlates_with(self) -> list[str]:
        """Names of the significant regressors, strongest first, each once."""
        out: list[str] = []
        for c in self.correlations:
            if c.significant and c.regressor not in out:
                out.append(c.regressor)
        return out

    def to_contract(self) -> dict[str, Any]:
        """The ``calbench diagnose --json`` object."""
        out: dict[str, Any] = {
            "unit": self.unit,
            "baseline": self.baseline.to_contract(),
            "mismatch": {
                "channels": {
                    ch: float(r) for ch, r in zip(("ax", "ay", "az"), self.channel_ratio, strict=True)
                },
                "where": self.where,
                "correlates_with": self.correlates_with(),
            },
            "findings": [f.to_contract() for f in self.findings],
            "discovered": [d.to_contract() for d in self.discovered],
            "final": self.final.to_contract(),
            "unobservable": dict(self.unobservable),
            "notes": list(self.notes),
        }
        if self.unexplained is not None:
            out["unexplained"] = self.unexplained.to_contract()
        return out


def finite_or_none(a: Any) -> Any:
    """Nested lists with non-finite numbers replaced by ``None`` (JSON has no NaN)."""
    if isinstance(a, (list, tuple)):
        return [finite_or_none(x) for x in a]
    if isinstance(a, float) and not np.isfinite(a):
        return None
    return a
