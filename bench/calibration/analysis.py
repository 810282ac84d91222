"""A recording analysed once: :func:`analyse` reads nothing and fits once; everything the run's
consumers need (the verdict, the stored fit, the certificate and its budget, the CLI, the drift
check) is taken from the one :class:`Analysis`, never from the recording again.

* the fit: a :class:`~bench.calibration.result.CalibrationResult` tagged by its
  :class:`~bench.calibration.kind.FitKind` (static, orientation-free or moving; the moving one
  a ``DynamicCalibrationResult``), which knows its terms, parameter names and text form;
* the nominal |g| check (:func:`with_nominal`): the |g| error of the raw outputs scaled by a
  unit's registered nominal scale s and zero-g output b₀, e = |(ȳ − b₀)/s| − g over the fit's
  windows (static) or 1 s blocks (moving) — no second fit;
* the budget's design (:func:`budget_design`): what the GUM budget of b and K needs of the fit
  beyond its values; for a static fit the specific force f_w (m, 3), the window means (m, 3)
  and their covariances V_w (m, 3, 3), the windows' mean table angles (m, k) and temperatures
  (m,), and whether the fit shared a slow wander between the windows; for a moving fit
  the model terms its sensitivities are refitted with (``bench.uncertainty.dynamic``);
* the diagnosis (:func:`with_diagnosis`), which the service adds after the verdict.

Everything here is pure: no database, no service; :func:`analyse` runs outside any transaction.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from bench.calibration.kind import FitKind
from bench.calibration.recording import calibrate_recording
from bench.calibration.result import CalibrationResult
from bench.calibration.static import NATURAL_ZERO_UNITS, nominal_force
from bench.calibration.windows import select_windows, table_window_angles, window_means
from bench.estimation.g_check import GCheck, g_check
from bench.fitted_model import FittedModel, GCheckSummary, NominalReference
from bench.recording import Recording
from bench.recording.model import TableGeometry

if TYPE_CHECKING:
    from bench.diagnosis.result import Diagnosis

FloatArray = npt.NDArray[np.float64]

Nominal = tuple[float, float | None]
"""A unit's registered nominal scale (channel unit per m/s²) and zero-g output (channel unit)."""

DIAGNOSIS_AVAILABLE = importlib.util.find_spec("bench.calibration.diagnose") is not None
"""The diagnosis module is installed (it is optional for the service)."""


@dataclass(frozen=True)
class StaticDesign:
    """The design of a known-orientation fit, as its budget reads it.

    :param f_m_s2: (m, 3) specific force of each window (m/s²).
    :param window_cov: (m, 3, 3) covariance of each window mean from its own samples, as the
        fit had it (``windows.window_means``; channel units²).
    :param table_rad: (m, k) mean encoder angles of the windows (rad), ``None`` without a table.
    :param table: the table's geometry (axes, mount) the angles turn, ``None`` without a table.
    :param temp_c: (m,) mean sensor temperature of the windows (°C), ``None`` when not recorded.
    :param y_mean: (m, 3) the window means the fit used (channel units).
    :param correlated_windows: the fit modelled a slow wander shared by the windows
        (``bias_reference == "long_run"``), not an independent excess per window.
    :param bias_sigma_run_mean: (3,) the fit's bias sigma against the run's mean bias
        (``StaticFit.bias_sigma_run_mean``, channel units), the bias's Type A beside a stated wander.
    :param span_s: from the first window's first sample to the last window's last (s): the
        span over which the bias is the run's mean.
    """

    f_m_s2: FloatArray
    window_cov: FloatArray
    table_rad: FloatArray | None
    table: TableGeometry | None
    temp_c: FloatArray | None
    y_mean: FloatArray
    correlated_windows: bool
    bias_sigma_run_mean: FloatArray
    span_s: float


@dataclass(frozen=True, eq=False)
class MovingDesign:
    """The design of a moving-table fit: the model terms beyond b and K (``ModelSpec.terms``),
    and the fit's bias sigma against the run's mean bias (3,) channel units
    (``DynamicFit.bias_sigma_run_mean``), the bias's Type A beside a stated wander."""

    terms: tuple[str, ...]
    bias_sigma_run_mean: FloatArray


BudgetDesign = StaticDesign | MovingDesign


@dataclass(frozen=True, eq=False)
class Analysis:
    """One recording, fitted once, with what its consumers need (module docstring).

    :param recording: the recording (read once, by the caller).
    :param fit: the fit; its ``kind`` is the one choice of :class:`FitKind`.
    :param g_before: the |g| check with a unit's registered nominal when the fit has no
        ``before`` of its own (:func:`with_nominal`), else ``None``.
    :param diagnosis: the diagnosis (:func:`with_diagnosis`), or ``None``.
    :param diagnosis_note: why there is no diagnosis (empty when there is one or none was asked).
    :param memo: results derived from this analysis once and kept with it (the budget's design,
        a certificate budget per Type B settings); shared by the copies ``with_*`` make.
    """

    recording: Recording
    fit: CalibrationResult
    g_before: GCheckSummary | None = None
    diagnosis: Diagnosis | None = None
    diagnosis_note: str = ""
    memo: dict[Any, Any] = field(default_factory=dict, repr=False)

    @property
    def kind(self) -> FitKind:
        """The kind of fit (static, orientation-free, moving)."""
        return self.fit.kind

    def fitted_model(self) -> FittedModel:
        """The fit as limits, certificates and exports read it, with the nominal |g| check."""
        model = self.fit.fitted_model()
        return model if self.g_before is None else replace(model, g_before=self.g_before)

    def contract(self) -> dict[str, Any]:
        """The ``calbench calibrate --json`` object of the fit, with ``g_check.before`` from the
        nominal when :func:`with_nominal` formed it: the one object stored for the run."""
        out = self.fit.to_contract()
        if self.g_before is not None:
            out["g_check"] = {**out["g_check"], "before": self.g_before.to_contract()}
        return out

    @property
    def g_check_windows(self) -> int | None:
        """Windows of a static fit's |g| check; ``None`` for a moving fit (its 1 s blocks)."""
        return None if self.kind is FitKind.MOVING else len(self.fit.windows)


def analyse(
    rec: Recording,
    *,
    nominal: Nominal | None = None,
    nominal_scale: float | None = None,
    nominal_bias: FloatArray | None = None,
    terms: tuple[str, ...] | None = None,
) -> Analysis:
    """Fit ``rec`` once (:func:`~bench.calibration.recording.calibrate_recording`).

    :param nominal: a unit's registered nominal for the |g| check before adjustment
        (:func:`with_nominal`), applied when the fit has no ``before`` of its own.
    :param nominal_scale: :param nominal_bias: :param terms: passed to ``calibrate_recording``.
    :raises ValueError: the recording cannot be calibrated (message starts with its path).
    """
    fit = calibrate_recording(rec, nominal_scale=nominal_scale, nominal_bias=nominal_bias, terms=terms)
    out = Analysis(rec, fit)
    return with_nominal(out, nominal) if nominal is not None else out


def nominal_g_check(analysis: Analysis, nominal: Nominal) -> GCheckSummary | None:
    """The |g| check of the analysed recording with a registered nominal (scale, zero-g output),
    with that nominal; ``None`` if it cannot be formed: a scale that is zero or not finite, or a
    V or count unit registered without its zero-g output (assuming 0 would be meaningless)."""
    scale, bias = nominal
    rec, fit = analysis.recording, analysis.fit
    if bias is None and rec.sidecar.channel_unit not in NATURAL_ZERO_UNITS:
        return None
    b0 = np.full(3, bias or 0.0)
    check: GCheck | None
    try:
        if fit.kind is FitKind.MOVING:
            from bench.calibration.dynamic import nominal_g_check as moving_check

            check = moving_check(rec, np.asarray(rec.accel_raw, dtype=float), scale, b0)
        else:
            y = np.array([w.mean_raw for w in fit.windows], dtype=float)
            f = nominal_force(rec, y, scale, b0)
            check = None if f is None else g_check(f, rec.sidecar.g_local_m_s2)
    except ValueError:
        return None
    if check is None:
        return None
    ref = NominalReference(scale, bias or 0.0, "unit registration")
    return GCheckSummary(check.mean_error_m_s2, check.std_m_s2, ref)


def with_nominal(analysis: Analysis, nominal: Nominal | None) -> Analysis:
    """``analysis`` with the nominal |g| check, when the fit has no ``before`` of its own and
    ``nominal`` is given (otherwise unchanged)."""
    if nominal is None or analysis.fit.g_before is not None or analysis.g_before is not None:
        return analysis
    return replace(analysis, g_before=nominal_g_check(analysis, nominal))


def with_diagnosis(analysis: Analysis) -> Analysis:
    """``analysis`` with the recording's diagnosis (``bench.calibration.diagnose``), or with
    why there is none (the module is not installed, or the recording cannot be diagnosed)."""
    if analysis.diagnosis is not None:
        return analysis
    if not DIAGNOSIS_AVAILABLE:
        note = "diagnosis not performed: the diagnosis module (bench.calibration.diagnose) is not installed"
        return replace(analysis, diagnosis_note=note)
    from bench.calibration.diagnose import diagnose_recording

    try:
        return replace(analysis, diagnosis=diagnose_recording(analysis.recording), diagnosis_note="")
    except ValueError as exc:
        return replace(analysis, diagnosis_note=f"diagnosis not performed: {exc}")


def budget_design(analysis: Analysis) -> BudgetDesign:
    """The design the budget of the fit needs (module docstring), formed once per analysis.

    :raises ValueError: the fit has none: an orientation-free fit knows no specific force per
        window.
    """
    key = "budget_design"
    if key not in analysis.memo:
        analysis.memo[key] = _design(analysis.recording, analysis.fit)
    design: BudgetDesign | str = analysis.memo[key]
    if isinstance(design, str):
        raise ValueError(design)
    return design


def _design(rec: Recording, fit: CalibrationResult) -> BudgetDesign | str:
    if fit.kind is FitKind.MOVING:
        from bench.calibration.dynamic import DynamicCalibrationResult

        assert isinstance(fit, DynamicCalibrationResult) and fit.fit is not None
        return MovingDesign(fit.model_terms, fit.fit.bias_sigma_run_mean)
    if fit.kind is not FitKind.STATIC or any(w.f_m_s2 is None for w in fit.windows):
        return f"the {fit.kind.value} fit has no known specific force per window"
    f = np.array([w.f_m_s2 for w in fit.windows], dtype=float)
    y = np.array([w.mean_raw for w in fit.windows], dtype=float)
    wins = select_windows(rec)
    _, S = window_means(rec, wins)
    angles, table = None, rec.sidecar.table
    if rec.table_deg is not None and table is not None:
        angles = table_window_angles(rec, wins)
    temps = None
    if rec.temp_c is not None:
        t = np.array([float(np.mean(rec.temp_c[w.start : w.stop])) for w in wins])
        temps = t if np.all(np.isfinite(t)) else None
    run_mean = fit.bias_sigma if fit.bias_sigma_run_mean is None else fit.bias_sigma_run_mean
    span_s = max(w.end_s for w in fit.windows) - min(w.start_s for w in fit.windows)
    return StaticDesign(f, S, angles, table, temps, y, fit.bias_reference == "long_run", run_mean, span_s)
