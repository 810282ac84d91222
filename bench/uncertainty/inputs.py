"""The Type B inputs of a static calibration bench, as moves of the fit's design.

Each builder returns :class:`~bench.uncertainty.budget.TypeBInput` objects: the change of every
window's specific force f_w (m/s²) or mean output y_w (channel units) per unit change of the
input, for the linearised budget of ``bench.uncertainty.budget``. Pure numpy; the table's
kinematics are those of ``bench.kinematics`` (R = Rot(u1, θ1)…Rot(uk, θk)·M, f = Rᵀ [0, 0, g]).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from bench.kinematics import attitude, rot, static_specific_force
from bench.uncertainty.budget import TypeBInput

FloatArray = npt.NDArray[np.float64]

_AXIS_LETTERS = ("x", "y", "z")
_STEP_RAD = 1e-6


def _force(
    axis_vectors: FloatArray, q: FloatArray, mount: FloatArray, g: float, tilt: FloatArray
) -> FloatArray:
    """f_w = (T R_w)ᵀ [0, 0, g] with the base tilted by the rotation T (3, 3)."""
    R = np.einsum("ab,wbc->wac", tilt, attitude(axis_vectors, q, mount))
    return static_specific_force(R, g)


def table_inputs(
    axis_vectors: FloatArray,
    angles_rad: FloatArray,
    mount: FloatArray,
    g_local_m_s2: float,
    *,
    angle_u_rad: float,
    tilt_u_rad: float,
    axis_names: Sequence[str] | None = None,
) -> list[TypeBInput]:
    """Inputs of the table: each axis's angle (one error common to every position: encoder
    zero and scale, the conservative case for the misalignments), and the levelling of the
    base about the room's x and y (a tilt T of the whole table, f_w = (T R_w)ᵀ [0, 0, g]).

    ∂f_w/∂X by central differences of the kinematics (``bench.kinematics``) with a 1 µrad step.

    :param axis_vectors: (k, 3) table axes; :param angles_rad: (m, k) each window's angles;
    :param mount: (3, 3) mount rotation; :param g_local_m_s2: local gravity (m/s²).
    """
    u_ax = np.asarray(axis_vectors, dtype=float)
    q = np.asarray(angles_rad, dtype=float).reshape(-1, u_ax.shape[0])
    names = list(axis_names) if axis_names else [f"axis {a + 1}" for a in range(u_ax.shape[0])]
    inputs = []
    for a in range(u_ax.shape[0]):
        step = np.zeros_like(q)
        step[:, a] = _STEP_RAD
        df = (
            _force(u_ax, q + step, mount, g_local_m_s2, np.eye(3))
            - _force(u_ax, q - step, mount, g_local_m_s2, np.eye(3))
        ) / (2 * _STEP_RAD)
        inputs.append(
            TypeBInput(
                f"table angle, {names[a]}",
                angle_u_rad,
                "rad",
                df_m_s2=df,
                group="table angle",
                basis="encoder accuracy, normal, common to all positions",
            )
        )
    for e, letter in ((np.eye(3)[0], "x"), (np.eye(3)[1], "y")):
        plus = _force(u_ax, q, mount, g_local_m_s2, rot(e, _STEP_RAD)[0])
        minus = _force(u_ax, q, mount, g_local_m_s2, rot(e, -_STEP_RAD)[0])
        inputs.append(
            TypeBInput(
                f"base levelling about {letter}",
                tilt_u_rad,
                "rad",
                df_m_s2=(plus - minus) / (2 * _STEP_RAD),
                group=f"base levelling {letter}",
                basis="levelling of the table base, normal",
            )
        )
    return inputs


def gravity_input(f_m_s2: FloatArray, g_local_m_s2: float, u_m_s2: float) -> TypeBInput:
    """The local gravity value: f_w ∝ g, ∂f_w/∂g = f_w / g."""
    f = np.asarray(f_m_s2, dtype=float)
    return TypeBInput(
        "local gravity g_local",
        u_m_s2,
        "m/s2",
        df_m_s2=f / g_local_m_s2,
        group="local gravity",
        basis="gravity survey or model, normal",
    )


def daq_inputs(
    y_model: FloatArray, gain_u_rel: float, offset_u: float, channel_unit: str
) -> list[TypeBInput]:
    """Each channel's DAQ gain (y_i → (1 + ε) y_i, ∂y_i/∂ε = y_i) and offset (∂y_i/∂o = 1)."""
    y = np.asarray(y_model, dtype=float)
    inputs = []
    for i, letter in enumerate(_AXIS_LETTERS):
        gain, off = np.zeros_like(y), np.zeros_like(y)
        gain[:, i], off[:, i] = y[:, i], 1.0
        inputs.append(
            TypeBInput(
                f"DAQ gain, channel {letter}",
                gain_u_rel,
                "1",
                dy=gain,
                group="DAQ gain",
                channel=i,
                basis="voltage reference and gain, normal",
            )
        )
        inputs.append(
            TypeBInput(
                f"DAQ offset, channel {letter}",
                offset_u,
                channel_unit,
                dy=off,
                group="DAQ offset",
                channel=i,
                basis="offset after zeroing, normal",
            )
        )
    return inputs


def temperature_inputs(
    temp_c: FloatArray, f_m_s2: FloatArray, K: FloatArray, bias_u_m_s2_per_k: float, scale_u_rel_per_k: float
) -> list[TypeBInput]:
    """The unit's temperature coefficients (unknown, zero mean) acting on the run's measured
    temperature changes: results are stated at the mean window temperature T̄, and channel i
    of window w moves by K_ii c_b,i (T_w − T̄) (bias coefficient c_b in m/s² per K) and by
    (K f_w)_i c_K,i (T_w − T̄) (relative scale coefficient c_K per K)."""
    dT = np.asarray(temp_c, dtype=float) - float(np.mean(temp_c))
    Km = np.asarray(K, dtype=float)
    out = np.asarray(f_m_s2, dtype=float) @ Km.T
    inputs = []
    for i, letter in enumerate(_AXIS_LETTERS):
        db, dk = np.zeros_like(out), np.zeros_like(out)
        db[:, i], dk[:, i] = Km[i, i] * dT, out[:, i] * dT
        inputs.append(
            TypeBInput(
                f"bias temperature coefficient, channel {letter}",
                bias_u_m_s2_per_k,
                "m/s2/K",
                dy=db,
                group="temperature: bias",
                channel=i,
                basis="unit's specification, with the run's temperature changes",
            )
        )
        inputs.append(
            TypeBInput(
                f"scale temperature coefficient, channel {letter}",
                scale_u_rel_per_k,
                "1/K",
                dy=dk,
                group="temperature: scale",
                channel=i,
                basis="unit's specification, with the run's temperature changes",
            )
        )
    return inputs
