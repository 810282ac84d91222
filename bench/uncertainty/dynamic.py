"""Uncertainty budget of a moving-table calibration (``calibrate_dynamic``) by refitting.

The dynamic fit takes as exact the same bench inputs as the static one (GUM, JCGM 100:2008):
each table axis's encoder angle, the levelling of the table base, the local gravity value, each
DAQ channel's gain and offset, and the unit's temperature coefficients. Their sensitivities
c = ∂θ/∂X (θ = [b, vec K], 12 parameters) are found by refitting (GUM 5.1.3, numerical
differentiation): the recording is changed as the input would change it,

* table angle, axis a:     encoder column a + h (one error common to all samples);
* base levelling about e:  the whole table tilted by T = Rot(e, h): axis vectors T u_i and
                           mount T M (T Rot(u_1, θ_1)…Rot(u_k, θ_k) M = Rot(T u_1, θ_1)…T M);
* local gravity:           sidecar g_local + h;
* DAQ gain, channel i:     raw_i (1 + h);   DAQ offset, channel i: raw_i + h;
* temperature, channel i:  raw_i + K_ii h (T − T̄) (bias coefficient, m/s² per K) or
                           raw_i + (raw_i − b_i) h (T − T̄) (relative scale coefficient per K),
                           results stated at the recording's mean temperature T̄;

refitted with ``calibrate_dynamic`` on the same model terms (no Kalman cross-check), and
c = (θ(+h) − θ(−h)) / 2h. The step is h = max(u(X), ``MIN_STEP``): the fit stops at a relative
cost decrease of 1e-8, so a step far below the data's noise would measure the optimiser's
tolerance, not the slope; the steps are small enough for the model to stay linear in them.

When the fit estimates the base tilt itself (term ``table_tilt``) the levelling inputs are not
evaluated: the tilt is a fitted parameter, and its uncertainty is already in the Type A
covariance of b and K. The budget is then combined exactly as the static one
(``bench.uncertainty.budget.combine``).

The bias a certificate carries is the unit's long-run bias; one run sees it plus the average
over the run of its slow wander. Given the unit's wander, the bias's Type A line is the fit's
sigma against the run's mean bias (``DynamicFit.bias_sigma_run_mean``) and the wander's
average over the fitted span is its own line per sensor axis (``bench.uncertainty.wander``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.calibration.dynamic import calibrate_dynamic
from bench.kinematics import rot
from bench.recording import Recording
from bench.recording.model import TableAxis
from bench.uncertainty.budget import Budget, TypeBInput, combine
from bench.uncertainty.wander import with_wander

FloatArray = npt.NDArray[np.float64]

TYPE_A_NAME = "Type A: sample noise and its correlation (fit's sandwich covariance)"
TYPE_A_RUN_MEAN_NAME = (
    "Type A: sample noise and its correlation (fit's sandwich covariance; bias against the run's mean)"
)
METHOD = "refit by central differences (calibrate_dynamic on the changed recording)"
TILT_ABSORBED = (
    "base levelling: the dynamic fit estimates the table tilt (table_tilt), so its uncertainty "
    "is already in the Type A covariance"
)
MIN_STEP = {
    "table angle": 1e-4,  # rad
    "base levelling": 1e-4,  # rad
    "local gravity": 1e-4,  # relative to g
    "DAQ gain": 1e-4,  # relative
    "DAQ offset": 1e-4,  # relative to g·K_ii (channel units)
    "temperature: bias": 1e-3,  # m/s² per K
    "temperature: scale": 1e-4,  # per K
}
"""Smallest refit step per input group (units as noted)."""
_LETTERS = ("x", "y", "z")

Change = Callable[[Recording, float], Recording]


@dataclass(frozen=True)
class DynamicInput:
    """One Type B input and how it changes a recording: ``change(rec, h)`` is ``rec`` with X moved by h."""

    input: TypeBInput
    change: Change
    step: float


def _raw(i: int, scale: FloatArray | float, shift: FloatArray | float) -> Change:
    """Channel i moved linearly in h: raw_i + h (scale · raw_i + shift)."""

    def change(rec: Recording, h: float) -> Recording:
        y = np.array(rec.accel_raw, dtype=float)
        y[:, i] = y[:, i] + h * (scale * y[:, i] + shift)
        return dataclasses.replace(rec, accel_raw=y)

    return change


def _angle(a: int) -> Change:
    def change(rec: Recording, h: float) -> Recording:
        assert rec.table_deg is not None
        q = np.array(rec.table_deg, dtype=float)
        q[:, a] += math.degrees(h)
        return dataclasses.replace(rec, table_deg=q)

    return change


def _vec3(v: FloatArray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _tilt(e: FloatArray) -> Change:
    def change(rec: Recording, h: float) -> Recording:
        geo = rec.sidecar.table
        assert geo is not None
        T = rot(e, h)[0]
        axes = tuple(TableAxis(a.name, _vec3(T @ np.asarray(a.axis))) for a in geo.axes)
        mount = tuple(_vec3(row) for row in T @ geo.mount_matrix)
        table = dataclasses.replace(geo, axes=axes, mount_rotation=mount)
        return dataclasses.replace(rec, sidecar=dataclasses.replace(rec.sidecar, table=table))

    return change


def _gravity(rec: Recording, h: float) -> Recording:
    sc = rec.sidecar
    return dataclasses.replace(rec, sidecar=dataclasses.replace(sc, g_local_m_s2=sc.g_local_m_s2 + h))


def dynamic_inputs(
    rec: Recording,
    terms: tuple[str, ...],
    bias: FloatArray,
    K: FloatArray,
    *,
    angle_u_rad: float,
    tilt_u_rad: float,
    g_local_u_m_s2: float,
    daq: tuple[float, float] | None,
    temp_coeff: tuple[float, float],
) -> tuple[list[DynamicInput], list[str]]:
    """The inputs of a moving-table recording fitted with the extra ``terms``, and what was not evaluated.

    :param bias: (3,) and :param K: (3, 3) the fit (channel units, per m/s²).
    :param daq: (gain u, relative; offset u, channel units) for an analog output, else ``None``.
    :param temp_coeff: (bias coefficient u, m/s² per K; relative scale coefficient u, per K).
    """
    b, Km = np.asarray(bias, dtype=float).reshape(3), np.asarray(K, dtype=float).reshape(3, 3)
    g = rec.sidecar.g_local_m_s2
    geo = rec.sidecar.table
    if geo is None or rec.table_deg is None:
        raise ValueError("a dynamic budget needs the table (sidecar 'table' and table_i columns)")
    out: list[DynamicInput] = []
    skipped: list[str] = []

    def add(inp: TypeBInput, change: Change, step: float) -> None:
        out.append(DynamicInput(inp, change, max(inp.u, step)))

    for a, ax in enumerate(geo.axes):
        add(TypeBInput(f"table angle, axis {ax.name}", angle_u_rad, "rad", group="table angle",
                       basis="encoder accuracy, normal, common to all samples"),
            _angle(a), MIN_STEP["table angle"])  # fmt: skip
    if "table_tilt" in terms:
        skipped.append(TILT_ABSORBED)
    else:
        for e, letter in ((np.eye(3)[0], "x"), (np.eye(3)[1], "y")):
            add(TypeBInput(f"base levelling about {letter}", tilt_u_rad, "rad",
                           group=f"base levelling {letter}", basis="levelling of the table base, normal"),
                _tilt(e), MIN_STEP["base levelling"])  # fmt: skip
    add(TypeBInput("local gravity g_local", g_local_u_m_s2, "m/s2", group="local gravity",
                   basis="gravity survey or model, normal"),
        _gravity, MIN_STEP["local gravity"] * g)  # fmt: skip
    unit = rec.sidecar.channel_unit
    if daq is not None:
        for i, letter in enumerate(_LETTERS):
            add(TypeBInput(f"DAQ gain, channel {letter}", daq[0], "1", group="DAQ gain", channel=i,
                           basis="voltage reference and gain, normal"),
                _raw(i, 1.0, 0.0), MIN_STEP["DAQ gain"])  # fmt: skip
            add(TypeBInput(f"DAQ offset, channel {letter}", daq[1], unit, group="DAQ offset", channel=i,
                           basis="offset after zeroing, normal"),
                _raw(i, 0.0, 1.0),
                MIN_STEP["DAQ offset"] * g * abs(Km[i, i]))  # fmt: skip
    else:
        skipped.append(f"DAQ gain and offset: the output ({unit}) is digital, not measured by the DAQ")
    temp = None if rec.temp_c is None else np.asarray(rec.temp_c, dtype=float)
    if temp is None or not np.all(np.isfinite(temp)):
        skipped.append("temperature coefficients: no sensor temperature was recorded")
        return out, skipped
    dT = temp - float(np.mean(temp))
    basis = "unit's specification, with the run's temperature changes"
    for i, letter in enumerate(_LETTERS):
        add(TypeBInput(f"bias temperature coefficient, channel {letter}", temp_coeff[0], "m/s2/K",
                       group="temperature: bias", channel=i, basis=basis),
            _raw(i, 0.0, Km[i, i] * dT),
            MIN_STEP["temperature: bias"])  # fmt: skip
        add(TypeBInput(f"scale temperature coefficient, channel {letter}", temp_coeff[1], "1/K",
                       group="temperature: scale", channel=i, basis=basis),
            _raw(i, dT, -b[i] * dT),  # (raw_i − b_i) h dT
            MIN_STEP["temperature: scale"])  # fmt: skip
    return out, skipped


def _theta(rec: Recording, terms: tuple[str, ...]) -> FloatArray:
    fit = calibrate_dynamic(rec, terms=terms, cross_check=False)
    return np.concatenate([fit.bias, fit.K.ravel()])


def refit_sensitivities(rec: Recording, terms: tuple[str, ...], inputs: list[DynamicInput]) -> FloatArray:
    """(n_inputs, 12) ∂θ/∂X by central differences of refits (2 refits per input)."""
    out = np.zeros((len(inputs), 12))
    for n, d in enumerate(inputs):
        plus, minus = _theta(d.change(rec, d.step), terms), _theta(d.change(rec, -d.step), terms)
        out[n] = (plus - minus) / (2.0 * d.step)
    return out


def dynamic_budget(
    rec: Recording,
    terms: tuple[str, ...],
    bias: FloatArray,
    K: FloatArray,
    cov_type_a: FloatArray,
    inputs: list[DynamicInput],
    wander: tuple[float, float] | None = None,
    bias_sigma_run_mean: FloatArray | None = None,
) -> Budget:
    """The budget of b and K of a dynamic fit (values ``bias``, ``K``; Type A ``cov_type_a`` (12, 12)).

    :param wander: the unit's bias wander (σ_w m/s², T_c s): the bias's Type A becomes the
        fit's sigma against the run's mean and the wander's average over the run its own line
        (module docstring), so the bias U is the long-run bias's; ``None``: the fit's sigma as
        it is (``bias_reference`` says which bias it describes).
    :param bias_sigma_run_mean: (3,) the fit's bias sigma against the run's mean
        (``DynamicFit.bias_sigma_run_mean``, channel units); required with ``wander``.
    :raises ValueError: a refit fails (the recording's message), or a non-finite covariance.
    """
    C = np.asarray(cov_type_a, dtype=float)
    if C.shape != (12, 12) or not np.all(np.isfinite(C)) or np.any(np.diag(C) < 0):
        raise ValueError(
            f"Type A covariance must be finite (12, 12) with a non-negative diagonal, got {C.shape}"
        )
    sens = refit_sensitivities(rec, terms, inputs)
    theta = np.concatenate([np.asarray(bias, dtype=float).reshape(3), np.asarray(K, dtype=float).ravel()])
    type_b = [d.input for d in inputs]
    if wander is None:
        return combine(theta, C, type_b, sens, METHOD, TYPE_A_NAME)
    if bias_sigma_run_mean is None:
        raise ValueError("the unit's bias wander needs the fit's bias sigma against the run's mean")
    span_s = float(rec.t_s[-1] - rec.t_s[0])
    C, w_inputs, w_sens = with_wander(C, bias_sigma_run_mean, span_s, K, wander)
    return combine(theta, C, [*type_b, *w_inputs], np.vstack([sens, w_sens]), METHOD, TYPE_A_RUN_MEAN_NAME)
