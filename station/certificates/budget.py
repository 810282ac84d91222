"""The certificate's uncertainty budget: Type B inputs of the bench from its settings, the fit's
design from the recording, the budget of ``bench.uncertainty.budget`` passed on typed
(:class:`CertificateBudget`) and written as JSON only into the certificate's content
(:meth:`CertificateBudget.to_content`).

The design is the run's analysis's (``bench.calibration.analysis.budget_design``: the windows
and specific forces of the one fit, or a moving fit's model terms), never a refit; values and
Type A standard uncertainties are the stored fit's (:class:`bench.fitted_model.FittedModel`),
for a static fit with an independent excess per window each σ times the factor that puts the
excess in the amount the data support, with the Type B inputs' expected share out of it
(``bench.uncertainty.type_a``, with its degrees of freedom; a fit with a slow wander shared by
the windows keeps its σ and says so). With the unit's bias wander stated
(``bias_wander_m_s2`` > 0) the bias's Type A line of both kinds is the fit's sigma against the
run's mean and the wander averaged over the run is its own line per sensor axis
(``bench.uncertainty.wander``), so the bias U is the unit's long-run bias's.
A moving fit's sensitivities are refits of the changed recording (``bench.uncertainty.dynamic``),
minutes of CPU: :func:`analysis_budget` forms a budget once per analysis and Type B settings,
before any database transaction opens. Inputs that do not apply are listed under ``not_evaluated``
with the reason (no table in the sidecar, no temperature channel, a digital output).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.calibration.analysis import Analysis, MovingDesign, StaticDesign, budget_design
from bench.estimation.static_design import PARAMETER_NAMES
from bench.fitted_model import FittedModel
from bench.recording import Recording
from bench.uncertainty.budget import RULE, TYPE_A_NAME, Budget, TypeBInput, uncertainty_budget
from bench.uncertainty.dynamic import METHOD as DYNAMIC_METHOD
from bench.uncertainty.dynamic import dynamic_budget, dynamic_inputs
from bench.uncertainty.inputs import daq_inputs, gravity_input, table_inputs, temperature_inputs
from bench.uncertainty.type_a import type_a_without_type_b
from bench.uncertainty.wander import with_wander

ANALOG_UNITS = ("V", "mV")
"""Channel units measured through the DAQ (its gain and offset apply)."""
TYPE_A_BASIS = (
    "the covariance of the fit's estimator: batch-means noise of each window and the scatter between "
    "windows (pose and each channel's own) estimated without bias (MINQUE at the fit's weights, not "
    "clipped at zero), with each Type B input's expected share of that scatter taken out (each input "
    "counted once); ν of each quantity by Satterthwaite from the scatter of that estimate"
)
CORRELATED_TYPE_A_BASIS = (
    "the fit's covariance: batch-means noise of each window and a slow wander shared by the windows; "
    "the Type B inputs' share of the scatter between windows is not taken out (it may be counted "
    "twice); ν = ∞ (the fit states the standard deviation of the Student-t of its variance components)"
)
DYNAMIC_TYPE_A_BASIS = (
    "the dynamic fit's covariance: Newey–West sandwich over blocks of the samples, never below "
    "the white-noise bound; ν = ∞ (many blocks)"
)
WANDER_BASIS = (
    "; the bias's Type A is its sigma against the run's mean bias, and the unit's bias wander "
    "(bias_wander_m_s2, bias_wander_corr_time_s) averaged over the run is its own line, so the "
    "bias U is that of the unit's long-run bias"
)
STATIC_TYPE_A_RUN_MEAN_NAME = (
    "Type A: window noise and between-window scatter (fit covariance; bias against the run's mean)"
)
STATIC_METHOD = "linearisation of the generalised least-squares fit (analytic derivative)"


@dataclass(frozen=True)
class TypeBSettings:
    """Type B standard uncertainties (k = 1) of a bench; see ``station.settings.Settings``."""

    table_angle_u_deg: float
    base_tilt_u_rad: float
    g_local_u_m_s2: float
    daq_gain_u_rel: float
    daq_offset_u: float
    temp_coeff_bias_u_m_s2_per_k: float
    temp_coeff_scale_u_rel_per_k: float
    bias_wander_m_s2: float = 0.0
    bias_wander_corr_time_s: float = 200.0

    @classmethod
    def of(cls, settings: Any) -> TypeBSettings:
        """The values from a ``Settings`` object (or anything with these attributes)."""
        return cls(**{name: float(getattr(settings, name)) for name in cls.__dataclass_fields__})


def _sig3(x: float) -> float:
    return float(f"{x:.3g}")


def budget_inputs(
    design: StaticDesign, g: float, stored: FittedModel, tb: TypeBSettings
) -> tuple[np.ndarray, np.ndarray, list[TypeBInput], list[str]]:
    """The design (f (m, 3), window covariances (m, 3, 3)), the Type B inputs and what was not evaluated.

    :param g: the recording's local gravity (m/s²).
    """
    f, S = design.f_m_s2, design.window_cov
    b, K = np.asarray(stored.bias, dtype=float), np.asarray(stored.K, dtype=float)
    inputs: list[TypeBInput] = [gravity_input(f, g, tb.g_local_u_m_s2)]
    skipped: list[str] = []
    angles, table = design.table_rad, design.table
    if angles is not None and table is not None and angles.shape[0] == f.shape[0]:
        inputs += table_inputs(
            table.axis_vectors, angles, table.mount_matrix, g,
            angle_u_rad=math.radians(tb.table_angle_u_deg), tilt_u_rad=tb.base_tilt_u_rad,
            axis_names=[f"axis {a.name}" for a in table.axes],
        )  # fmt: skip
    else:
        skipped.append("table angles and base levelling: the recording has no table angles")
    unit = stored.channel_unit
    if unit in ANALOG_UNITS:
        inputs += daq_inputs(b + f @ K.T, tb.daq_gain_u_rel, tb.daq_offset_u, unit)
    else:
        skipped.append(f"DAQ gain and offset: the output ({unit}) is digital, not measured by the DAQ")
    temps = design.temp_c
    if temps is not None and temps.shape[0] == f.shape[0]:
        inputs += temperature_inputs(
            temps, f, K, tb.temp_coeff_bias_u_m_s2_per_k, tb.temp_coeff_scale_u_rel_per_k
        )
    else:
        skipped.append("temperature coefficients: no sensor temperature was recorded")
    return f, S, inputs, skipped


@dataclass(frozen=True)
class CertificateBudget:
    """The budget a certificate states: the typed budget of the 12 parameters, with what the
    certificate says about it.

    :param budget: u_c, ν_eff, k and U of each parameter (``PARAMETER_NAMES`` order) and the
        contributions |c_i|·u(x_i) behind them.
    :param channel_unit: the unit of the biases (the scale matrix's is per m/s²).
    :param not_evaluated: inputs that do not apply, each with the reason.
    :param type_a_basis: where the Type A part comes from. :param sensitivity_method: how the
        sensitivities c_i were found.
    """

    budget: Budget
    channel_unit: str
    not_evaluated: tuple[str, ...]
    type_a_basis: str = TYPE_A_BASIS
    sensitivity_method: str = STATIC_METHOD

    def combined(self, quantity: str) -> tuple[np.ndarray, float]:
        """u_c of ``"bias"`` (3,) or ``"scale_matrix"`` (3, 3), in the quantity's unit, and its
        coverage factor: the largest k of its elements, each k as the certificate states it (three
        decimals), so one k per quantity, never smaller than any element's own.

        :raises ValueError: ``quantity`` is neither ``"bias"`` nor ``"scale_matrix"``.
        """
        if quantity not in ("bias", "scale_matrix"):
            raise ValueError(f"budget quantity {quantity!r}: expected 'bias' or 'scale_matrix'")
        names = PARAMETER_NAMES[:3] if quantity == "bias" else PARAMETER_NAMES[3:]
        qs = [self.budget.by_name(n) for n in names]
        u = np.array([q.u_c for q in qs], dtype=float)
        return (u if quantity == "bias" else u.reshape(3, 3)), max(round(q.k, 3) for q in qs)

    def to_content(self) -> dict[str, Any]:
        """The budget as the certificate's JSON (``results.uncertainty_budget``): inputs, and per
        parameter its lines, u_c, ν_eff, k and U (contributions and U to three significant
        digits, u_c unrounded, k to three decimals; ν_eff ``"infinite"`` when every contribution
        has ν = ∞)."""
        budget, unit = self.budget, self.channel_unit
        units = [unit] * 3 + [f"{unit}/(m/s2)"] * 9
        quantities: dict[str, Any] = {}
        for q, qunit in zip(budget.quantities, units, strict=True):
            lines = [
                {"name": c.name, "group": c.group, "channel": c.channel, "u": _sig3(c.u), "unit": c.unit,
                 "sensitivity": _sig3(c.sensitivity), "contribution": _sig3(c.contribution)}
                for c in q.contributions
                if c.group == "Type A" or c.contribution > 1e-6 * q.u_c
            ]  # fmt: skip
            quantities[q.name] = {
                "value": q.value, "unit": qunit, "u_c": q.u_c, "k": round(q.k, 3), "U": _sig3(q.U),
                "nu_eff": "infinite" if math.isinf(q.nu_eff) else round(q.nu_eff, 1), "contributions": lines,
            }  # fmt: skip
        return {
            "rule": RULE,
            "type_a": self.type_a_basis,
            "sensitivity_method": self.sensitivity_method,
            "inputs": [
                {
                    "name": i.name,
                    "group": i.group,
                    "u": i.u,
                    "unit": i.unit,
                    "basis": i.basis,
                    "dof": "infinite" if math.isinf(i.dof) else i.dof,
                }
                for i in budget.inputs
            ],
            "not_evaluated": list(self.not_evaluated),
            "quantities": quantities,
        }


def certificate_budget(analysis: Analysis, stored: FittedModel, tb: TypeBSettings) -> CertificateBudget:
    """The budget of a stored fit whose analysis is ``analysis``: the static budget of its
    design, or for a moving fit the budget of ``bench.uncertainty.dynamic`` (sensitivities by
    refits with the fit's own model terms).

    :raises ValueError: the fit has no design (an orientation-free fit), or a refit fails.
    """
    sigma = np.concatenate([np.asarray(stored.bias_sigma, float), np.asarray(stored.K_sigma, float).ravel()])
    b, K = np.asarray(stored.bias, dtype=float), np.asarray(stored.K, dtype=float)
    design = budget_design(analysis)
    rec = analysis.recording
    if isinstance(design, MovingDesign):
        return _dynamic_budget(rec, design, stored.channel_unit, tb, b, K, np.diag(sigma**2))
    f, V, inputs, skipped = budget_inputs(design, rec.sidecar.g_local_m_s2, stored, tb)
    wander = (tb.bias_wander_m_s2, tb.bias_wander_corr_time_s) if tb.bias_wander_m_s2 > 0 else None
    if design.correlated_windows:
        cov_a, known, name = _static_wander(np.diag(sigma**2), design.bias_sigma_run_mean, design, K, wander)
        budget = uncertainty_budget(f, b, K, cov_a, inputs, window_cov=V, known=known, type_a_name=name)
        basis = CORRELATED_TYPE_A_BASIS + ("" if wander is None else WANDER_BASIS)
        return CertificateBudget(budget, stored.channel_unit, tuple(skipped), basis)
    type_a = type_a_without_type_b(f, design.y_mean, V, K, inputs)
    sigma_a = sigma * type_a.ratio()
    # independent window errors: the Type A line's bias sigma is already against the run's mean
    cov_a, known, name = _static_wander(np.diag(sigma_a**2), sigma_a[:3], design, K, wander)
    budget = uncertainty_budget(
        f,
        b,
        K,
        cov_a,
        inputs,
        window_cov=type_a.weights_cov,
        type_a_dof=type_a.dof,
        known=known,
        type_a_name=name,
    )
    basis = f"{TYPE_A_BASIS}; excess model: {type_a.model}" + ("" if wander is None else WANDER_BASIS)
    if type_a.below_zero:
        basis += "; estimated below zero (no excess shown): " + ", ".join(type_a.below_zero)
    if type_a.floored:
        basis += "; held at half the within-window variance: " + ", ".join(type_a.floored)
    return CertificateBudget(budget, stored.channel_unit, tuple(skipped), basis)


def _static_wander(
    cov_a: np.ndarray,
    bias_sigma_run_mean: np.ndarray,
    design: StaticDesign,
    K: np.ndarray,
    wander: tuple[float, float] | None,
) -> tuple[np.ndarray, tuple[list[TypeBInput], np.ndarray] | None, str]:
    """The static Type A covariance, the wander's lines and the Type A line's name
    (``bench.uncertainty.wander``): unchanged without a stated wander; with independent window
    errors the bias's Type A is already against the run's mean (``bias_sigma_run_mean`` is the
    line's own bias sigma) and only the lines are added."""
    if wander is None:
        return cov_a, None, TYPE_A_NAME
    C, w_inputs, w_sens = with_wander(cov_a, bias_sigma_run_mean, design.span_s, K, wander)
    # independent window errors: the line is the same as without the wander, and so its name
    name = STATIC_TYPE_A_RUN_MEAN_NAME if design.correlated_windows else TYPE_A_NAME
    return C, (w_inputs, w_sens), name


def analysis_budget(
    analysis: Analysis, stored: FittedModel, tb: TypeBSettings
) -> tuple[CertificateBudget | None, str]:
    """:func:`certificate_budget`, or ``None`` and why not; formed once per analysis, stored fit
    values and Type B settings (kept in ``analysis.memo``), so the verdict's guard band and the
    certificate share one budget."""
    key = ("certificate_budget", tb, _values(stored))
    if key not in analysis.memo:
        try:
            analysis.memo[key] = (certificate_budget(analysis, stored, tb), "")
        except (KeyError, ValueError) as exc:
            analysis.memo[key] = (None, f"budget not formed: {exc}")
    result: tuple[CertificateBudget | None, str] = analysis.memo[key]
    return result


def _values(stored: FittedModel) -> tuple[str | float, ...]:
    """The stored unit, values and sigmas a budget is formed from, as a key."""
    parts = (stored.bias, stored.K, stored.bias_sigma, stored.K_sigma)
    return (stored.channel_unit, *(float(v) for p in parts for v in np.ravel(p)))


def _dynamic_budget(
    rec: Recording,
    design: MovingDesign,
    unit: str,
    tb: TypeBSettings,
    b: np.ndarray,
    K: np.ndarray,
    cov: np.ndarray,
) -> CertificateBudget:
    inputs, skipped = dynamic_inputs(
        rec, design.terms, b, K,
        angle_u_rad=math.radians(tb.table_angle_u_deg), tilt_u_rad=tb.base_tilt_u_rad,
        g_local_u_m_s2=tb.g_local_u_m_s2,
        daq=(tb.daq_gain_u_rel, tb.daq_offset_u) if unit in ANALOG_UNITS else None,
        temp_coeff=(tb.temp_coeff_bias_u_m_s2_per_k, tb.temp_coeff_scale_u_rel_per_k),
    )  # fmt: skip
    wander = (tb.bias_wander_m_s2, tb.bias_wander_corr_time_s) if tb.bias_wander_m_s2 > 0 else None
    budget = dynamic_budget(
        rec, design.terms, b, K, cov, inputs, wander=wander, bias_sigma_run_mean=design.bias_sigma_run_mean
    )
    basis = DYNAMIC_TYPE_A_BASIS if wander is None else DYNAMIC_TYPE_A_BASIS + WANDER_BASIS
    return CertificateBudget(budget, unit, tuple(skipped), basis, DYNAMIC_METHOD)
