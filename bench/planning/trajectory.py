"""The specific force a procedure of moves and dwells applies to the sensor, sample by sample.

A :class:`~bench.procedures.steps.MoveTo` moves every axis at once, each on its own trapezoidal
profile (``bench.procedures.preview.move_time_s``: acceleration a to the rate v, coast,
deceleration; a triangle when the distance is short), and the step lasts as long as the slowest
axis, then ``settle_s`` of rest; a :class:`~bench.procedures.steps.Dwell` holds the pose. The
sensor sits at the table's centre, so its specific force is gravity seen in the sensor frame,

    f(t) = R(t)ᵀ·[0, 0, g],   R = Rz(outer)·Rx(middle)·Rz(inner)  (base from sensor),

(m/s², the default geometry of ``bench.planning.evaluation.rotation_deg``). The centripetal and
tangential terms of an off-centre sensor and a tilted base are nuisance parameters of the fit
(:func:`nuisance_response`): a lever arm r (table frame, m) adds B(t)·r with B = Rᵀ([ω̇]× + [ω]×²)R
(ω, ω̇ of the innermost frame in base coordinates, ``bench.kinematics``; the axis rates and
accelerations by central differences of the sampled angles), and a base tilt δ = (δ_x, δ_y)
(rad) turns gravity to g·(δ_y, −δ_x, 1), adding Rᵀ·g·[[0, 1], [−1, 0], [0, 0]]·δ.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from bench.kinematics import angular_acceleration, angular_velocity
from bench.procedures.preview import DEFAULT_TABLE_LIMITS, TableLimits, move_time_s
from bench.procedures.steps import Dwell, MoveTo, Procedure

FloatArray = npt.NDArray[np.float64]

AXES = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
"""Axis vectors of R = Rz(outer)·Rx(middle)·Rz(inner), outermost first."""
NUISANCE_NAMES = ("r_x_m", "r_y_m", "r_z_m", "tilt_x_rad", "tilt_y_rad")
"""The columns of :func:`nuisance_response`."""


def trapezoid_deg(t_s: FloatArray, distance_deg: float, rate_deg_s: float, acc_deg_s2: float) -> FloatArray:
    """Angle travelled (deg) at times ``t_s`` (s from the move's start) on the trapezoidal profile."""
    d = abs(distance_deg)
    sign = 1.0 if distance_deg >= 0 else -1.0
    if d == 0.0:
        return np.zeros_like(t_s)
    total = move_time_s(d, rate_deg_s, acc_deg_s2)
    t = np.clip(t_s, 0.0, total)
    v_peak = min(rate_deg_s, math.sqrt(d * acc_deg_s2))
    t_acc = v_peak / acc_deg_s2
    s = np.where(
        t < t_acc,
        0.5 * acc_deg_s2 * t**2,
        np.where(
            t <= total - t_acc,
            0.5 * acc_deg_s2 * t_acc**2 + v_peak * (t - t_acc),
            d - 0.5 * acc_deg_s2 * (total - t) ** 2,
        ),
    )
    return sign * s


def rotations(angles_deg: FloatArray) -> FloatArray:
    """(n, 3, 3) R = Rz(outer)·Rx(middle)·Rz(inner) for angles (n, 3) in degrees."""
    o, m, i = (np.radians(angles_deg[:, k]) for k in range(3))
    co, so, cm, sm, ci, si = np.cos(o), np.sin(o), np.cos(m), np.sin(m), np.cos(i), np.sin(i)
    R = np.empty((len(o), 3, 3))
    R[:, 0, 0] = co * ci - so * cm * si
    R[:, 0, 1] = -co * si - so * cm * ci
    R[:, 0, 2] = so * sm
    R[:, 1, 0] = so * ci + co * cm * si
    R[:, 1, 1] = -so * si + co * cm * ci
    R[:, 1, 2] = -co * sm
    R[:, 2, 0] = sm * si
    R[:, 2, 1] = sm * ci
    R[:, 2, 2] = cm
    return R


def angle_trajectory(
    proc: Procedure, fs_hz: float, limits: TableLimits = DEFAULT_TABLE_LIMITS
) -> tuple[FloatArray, FloatArray]:
    """(t (n,) s, angles (n, 3) deg) of a procedure of MoveTo and Dwell steps sampled at ``fs_hz``.

    The table starts at zero angles; every move takes the shortest way on a continuous axis.

    :raises ValueError: a step that is neither MoveTo nor a fixed Dwell, or not a 3-axis table.
    """
    t, ang, _ = angle_trajectory_steps(proc, fs_hz, limits)
    return t, ang


def angle_trajectory_steps(
    proc: Procedure, fs_hz: float, limits: TableLimits = DEFAULT_TABLE_LIMITS
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.int64]]:
    """:func:`angle_trajectory` and, per step, the number of samples once it is done (n_steps,)."""
    if limits.n_axes != 3 or proc.n_axes != 3:
        raise ValueError(f"{proc.name}: the trajectory needs a 3-axis table and procedure")
    dt = 1.0 / fs_hz
    pos = np.zeros(3)
    pieces: list[FloatArray] = []
    ends: list[int] = []
    n_done = 0
    for i, step in enumerate(proc.steps):
        first = len(pieces)
        if isinstance(step, MoveTo):
            target = np.asarray(step.angles_deg, dtype=float)
            dist = target - pos
            for ax in range(3):
                if limits.continuous[ax]:
                    dist[ax] = (dist[ax] + 180.0) % 360.0 - 180.0
            dur = max(
                move_time_s(abs(dist[ax]), limits.max_rate_deg_s[ax], limits.max_acc_deg_s2[ax])
                for ax in range(3)
            )
            n = round(dur / dt)
            tt = np.arange(n, dtype=float) * dt
            seg = np.stack(
                [
                    pos[ax]
                    + trapezoid_deg(tt, dist[ax], limits.max_rate_deg_s[ax], limits.max_acc_deg_s2[ax])
                    for ax in range(3)
                ],
                axis=1,
            )
            pieces.append(seg)
            pos = pos + dist
            pieces.append(np.repeat(pos[None], round(step.settle_s / dt), axis=0))
        elif isinstance(step, Dwell):
            if step.duration_s is None:
                raise ValueError(f"{proc.name}: step {i} ({step.label}): the dwell must be fixed")
            pieces.append(np.repeat(pos[None], round(step.duration_s / dt), axis=0))
        else:
            raise ValueError(
                f"{proc.name}: step {i} is a {type(step).__name__}; only MoveTo and Dwell are sampled"
            )
        n_done += sum(len(p) for p in pieces[first:])
        ends.append(n_done)
    ang = np.concatenate(pieces) if pieces else np.zeros((0, 3))
    return np.arange(len(ang), dtype=float) * dt, ang, np.array(ends, dtype=np.int64)


def specific_force(angles_deg: FloatArray, g_m_s2: float = 9.80665) -> FloatArray:
    """(n, 3) f = Rᵀ·[0, 0, g] (m/s²) in the sensor frame."""
    return rotations(angles_deg)[:, 2, :] * g_m_s2


def nuisance_response(angles_deg: FloatArray, fs_hz: float, g_m_s2: float = 9.80665) -> FloatArray:
    """(n, 3, 5) ∂f/∂(r, δ) along a sampled trajectory (module docstring): the lever arm's
    three columns B(t) (1/s²) and the tilt's two (m/s² per rad).

    :param angles_deg: (n, 3) angles sampled at ``fs_hz`` (:func:`angle_trajectory`).
    """
    q = np.radians(np.asarray(angles_deg, dtype=float))
    dt = 1.0 / fs_hz
    rate = np.gradient(q, dt, axis=0)
    acc = np.gradient(rate, dt, axis=0)
    R = rotations(np.asarray(angles_deg, dtype=float))
    out = np.empty((len(q), 3, 5))
    # at rest (every axis rate and acceleration exactly 0) ω = ω̇ = 0 and the lever arm's columns
    # are 0: B(t) is taken on the moving samples only, each sample on its own
    moving = np.any(rate != 0.0, axis=1) | np.any(acc != 0.0, axis=1)
    out[:, :, :3] = 0.0
    if np.any(moving):
        qm, rm, am, Rm = q[moving], rate[moving], acc[moving], R[moving]
        w = angular_velocity(AXES, qm, rm)
        wd = angular_acceleration(AXES, qm, rm, am)
        A = _skew(wd) + _skew(w) @ _skew(w)
        out[moving, :, :3] = np.transpose(Rm, (0, 2, 1)) @ A @ Rm
    D = g_m_s2 * np.array([[0.0, 1.0], [-1.0, 0.0], [0.0, 0.0]])
    out[:, :, 3:] = np.einsum("nji,jk->nik", R, D)
    return out


def _skew(v: FloatArray) -> FloatArray:
    S = np.zeros((len(v), 3, 3))
    S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    S[:, 1, 0], S[:, 2, 0], S[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return S
