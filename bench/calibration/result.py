"""Typed results of a calibration: one window (:class:`WindowResult`) and one fit
(:class:`CalibrationResult`), turned into the ``calbench calibrate --json`` object of
``docs/cli-contract.md`` only by :meth:`CalibrationResult.to_contract`; what limits,
certificates and exports read of it is :meth:`CalibrationResult.fitted_model`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from bench.calibration.kind import FitKind
from bench.calibration.windows import UnusedWindow
from bench.estimation.dynamic_batch import BiasReference
from bench.estimation.g_check import GCheck
from bench.estimation.scalar_fit import PARAMETER_NAMES as SCALAR_NAMES
from bench.estimation.static_design import PARAMETER_NAMES as STATIC_NAMES
from bench.fit_kind import ORIENTATION_FREE_TERMS
from bench.fitted_model import FittedModel, GCheckSummary

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class WindowResult:
    """One static window of a calibration.

    :param label: segment label or detected-window name.
    :param start_s: first sample time (s).
    :param end_s: last sample time (s).
    :param n_samples: samples averaged.
    :param mean_raw: (3,) window mean (channel units).
    :param mean_sigma: (3,) standard deviation of that mean (channel units).
    :param f_m_s2: (3,) specific force the fit assumed (m/s²), ``None`` for the scalar fit.
    :param residual: (3,) mean − model (channel units) for the known-orientation fit;
        for the scalar fit the |g| residual mapped to channel units along f̂.
    :param normalized_residual: (3,) residual over its standard deviation (known-orientation
        fit), or (|f̂| − g) / σ repeated (scalar fit).
    :param g_error_after_m_s2: |K⁻¹(mean − b)| − g.
    :param g_error_before_m_s2: the same with the nominal scale, or ``None``.
    """

    label: str
    start_s: float
    end_s: float
    n_samples: int
    mean_raw: FloatArray
    mean_sigma: FloatArray
    f_m_s2: FloatArray | None
    residual: FloatArray
    normalized_residual: FloatArray
    g_error_after_m_s2: float
    g_error_before_m_s2: float | None


@dataclass(frozen=True)
class CalibrationResult:
    """A fitted first-order model of one recording, with its evidence.

    :param kind: :class:`~bench.calibration.kind.FitKind`: ``STATIC`` (known orientations),
        ``ORIENTATION_FREE`` (|f| = g only) or ``MOVING`` (the instance is then a
        :class:`bench.calibration.dynamic.DynamicCalibrationResult`).
    :param bias: (3,) channel units.
    :param K: (3, 3) channel unit per m/s² (lower-triangular L for ``"scalar"``).
    :param cov: (p, p) in :attr:`parameter_names` order: 12 for ``STATIC``
        (``static_design.PARAMETER_NAMES``), 9 for ``ORIENTATION_FREE``
        (``scalar_fit.PARAMETER_NAMES``), bias and K then the extra terms for ``MOVING``.
    :param bias_sigma: (3,); :param K_sigma: (3, 3) one-sigma (Type A) uncertainties.
    :param residual_rms: RMS of the window residuals (channel units); for ``MOVING`` the
        RMS of the per-sample residuals.
    :param chi2: residual χ² against the within-window noise; :param dof: its degrees of
        freedom. For ``MOVING``, whose residuals are scaled by their own fitted sigma,
        ``chi2`` is 3·n_samples by construction and carries no goodness-of-fit information.
    :param unused_windows: declared segments / detected windows the fit left out, with why.
    :param warnings: what the reader must know before trusting the numbers (zero
        redundancy, unused windows), one sentence each.
    :param bias_reference: what ``bias_sigma`` describes: ``"long_run"`` when a wander shared
        by the windows (or the blocks of a moving run) is in the covariance, so the sigma
        covers the unit's long-run bias; ``"run_mean"`` when it covers only the run's mean bias.
    :param bias_sigma_run_mean: (3,) a known-orientation static fit's bias sigma against the
        run's mean bias (``StaticFit.bias_sigma_run_mean``), the Type A line beside a stated
        unit wander; ``None`` for the other fits (a moving fit carries its own in ``fit``).
    """

    unit_serial: str
    channel_unit: str
    procedure: str
    kind: FitKind
    g_local_m_s2: float
    bias: FloatArray
    K: FloatArray
    cov: FloatArray
    bias_sigma: FloatArray
    K_sigma: FloatArray
    residual_rms: float
    chi2: float
    dof: int
    noise_model: str
    g_after: GCheck
    g_before: GCheck | None
    windows: tuple[WindowResult, ...]
    source: str = ""
    unused_windows: tuple[UnusedWindow, ...] = ()
    warnings: tuple[str, ...] = ()
    bias_reference: BiasReference = "run_mean"
    bias_sigma_run_mean: FloatArray | None = None

    @property
    def zero_redundancy(self) -> bool:
        """As many fitted parameters as observations: nothing checks the model (``dof`` 0)."""
        return self.kind is not FitKind.MOVING and self.dof <= 0

    @property
    def terms(self) -> list[str]:
        """Model terms fitted, as listed in the contract."""
        if self.kind is FitKind.ORIENTATION_FREE:
            return list(ORIENTATION_FREE_TERMS)
        return ["bias", "scale_matrix"]

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """The names of :attr:`cov`'s rows, in order."""
        return tuple(SCALAR_NAMES if self.kind is FitKind.ORIENTATION_FREE else STATIC_NAMES)

    def covariance_rows(self) -> tuple[tuple[tuple[float, ...], ...], tuple[str, ...]]:
        """:attr:`cov` as nested tuples of floats, with :attr:`parameter_names`.

        :raises ValueError: the covariance and the names differ in size.
        """
        names = self.parameter_names
        cov = tuple(tuple(float(v) for v in row) for row in np.asarray(self.cov, dtype=float))
        if len(cov) != len(names):
            raise ValueError(f"fit covariance is {len(cov)}x{len(cov)} for {len(names)} parameter names")
        return cov, names

    def model_lines(self) -> list[str]:
        """Lines ``calbench calibrate`` prints about terms beyond bias and K (none here)."""
        return []

    def fitted_model(self) -> FittedModel:
        """The fitted model as limits, certificates and exports read it (the values of
        :meth:`to_contract`, typed)."""
        return FittedModel(
            unit_serial=self.unit_serial,
            channel_unit=self.channel_unit,
            procedure=self.procedure,
            bias=self.bias,
            bias_sigma=self.bias_sigma,
            K=self.K,
            K_sigma=self.K_sigma,
            terms=tuple(self.terms),
            residual_rms=self.residual_rms,
            g_after=_g_summary(self.g_after),
            g_before=None if self.g_before is None else _g_summary(self.g_before),
            bias_reference=self.bias_reference,
        )

    def to_contract(self) -> dict[str, Any]:
        """The ``calbench calibrate --json`` object (docs/cli-contract.md)."""
        g_check_out: dict[str, Any] = {}
        if self.g_before is not None:
            g_check_out["before"] = _g_dict(self.g_before)
        g_check_out["after"] = _g_dict(self.g_after)
        return {
            "unit": self.unit_serial,
            "channel_unit": self.channel_unit,
            "procedure": self.procedure,
            "bias": self.bias.tolist(),
            "bias_sigma": self.bias_sigma.tolist(),
            "scale_matrix": self.K.tolist(),
            "scale_matrix_sigma": self.K_sigma.tolist(),
            "terms": self.terms,
            "extra": {},
            "residual_rms": self.residual_rms,
            "g_check": g_check_out,
            "dof": int(self.dof),
            "zero_redundancy": self.zero_redundancy,
            "unused_windows": [u.to_contract() for u in self.unused_windows],
            "warnings": list(self.warnings),
            "bias_reference": self.bias_reference,
        }


def _g_summary(g: GCheck) -> GCheckSummary:
    return GCheckSummary(g.mean_error_m_s2, g.std_m_s2)


def _g_dict(g: GCheck) -> dict[str, float]:
    return {"mean_error_m_s2": g.mean_error_m_s2, "std_m_s2": g.std_m_s2}


def zero_redundancy_warning(n_obs: int, n_params: int, what: str) -> str:
    """The sentence of a fit with no redundancy (``n_obs`` == ``n_params``)."""
    return (
        f"zero redundancy: {n_obs} {what} for {n_params} parameters, so the fit passes through "
        "every window exactly; residuals, chi2 and the |g| scatter are zero by construction and "
        "test nothing, and the sigmas rest on the within-window noise alone. Record more windows."
    )
