"""Rigid-body kinematics of a multi-axis table, written independently of ``bench.kinematics``.

Conventions of ``docs/recording-format.md``: base frame z up; ``Rot(u, θ)`` right-handed;
attitude of the innermost table frame R_inner = Rot(u1, θ1)·…·Rot(uN, θN) (outermost
first); sensor attitude R = R_inner·M. Axis i turns about u_i expressed in its parent
frame, i.e. about R_{<i}·u_i in base coordinates, where R_{<i} = Rot(u1, θ1)·…·Rot(u_{i−1},
θ_{i−1}).

Angular velocity and acceleration of the innermost frame in base coordinates
(Craig, *Introduction to Robotics*, eqs. 6.31-6.32 for a chain of revolute joints):

    ω   = Σ_i θ̇_i · a_i,                    a_i = R_{<i}·u_i
    ω̇  = Σ_i (θ̈_i · a_i + ω_{<i} × θ̇_i·a_i),  ω_{<i} = Σ_{j<i} θ̇_j·a_j

Specific force at a point p = R_inner·r (r fixed in the innermost frame), sensor frame:

    f = Rᵀ · (g_base + ω̇ × p + ω × (ω × p))
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def rot(axis: FloatArray, theta_rad: FloatArray) -> FloatArray:
    """Rodrigues rotation matrices.

    :param axis: (3,) unit vector.
    :param theta_rad: (n,) angles (rad).
    :returns: (n, 3, 3) matrices Rot(axis, θ) = I + sin θ·[u]× + (1 − cos θ)·[u]×².
    """
    u = np.asarray(axis, dtype=float)
    th = np.asarray(theta_rad, dtype=float).reshape(-1)
    ux = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    ux2 = ux @ ux
    out: FloatArray = np.eye(3) + np.sin(th)[:, None, None] * ux + (1.0 - np.cos(th))[:, None, None] * ux2
    return out


def rot_xy(a_rad: float | FloatArray, b_rad: float | FloatArray) -> FloatArray:
    """Rot(x, a)·Rot(y, b) for (n,) or scalar angles -> (n, 3, 3)."""
    a = np.atleast_1d(np.asarray(a_rad, dtype=float))
    b = np.atleast_1d(np.asarray(b_rad, dtype=float))
    out: FloatArray = np.einsum(
        "nij,njk->nik", rot(np.array([1.0, 0.0, 0.0]), a), rot(np.array([0.0, 1.0, 0.0]), b)
    )
    return out


def chain_state(
    axis_vectors: FloatArray, angles_rad: FloatArray, rates_rad_s: FloatArray, accels_rad_s2: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Attitude, angular velocity and angular acceleration of the innermost table frame.

    :param axis_vectors: (k, 3) unit axes, outermost first, each in its parent frame.
    :param angles_rad: (n, k) true axis angles.
    :param rates_rad_s: (n, k) axis rates.
    :param accels_rad_s2: (n, k) axis angular accelerations.
    :returns: R_inner (n, 3, 3), ω (n, 3) rad/s and ω̇ (n, 3) rad/s², both in base coordinates.
    """
    axes = np.asarray(axis_vectors, dtype=float)
    n, k = angles_rad.shape
    r_parent = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    omega = np.zeros((n, 3))
    omega_dot = np.zeros((n, 3))
    for i in range(k):
        a_i = r_parent @ axes[i]  # (n, 3) axis i in base coordinates
        w_i = rates_rad_s[:, i : i + 1] * a_i
        omega_dot += accels_rad_s2[:, i : i + 1] * a_i + np.cross(omega, w_i)
        omega += w_i
        r_parent = np.einsum("nij,njk->nik", r_parent, rot(axes[i], angles_rad[:, i]))
    return r_parent, omega, omega_dot


def specific_force_at(
    r_inner: FloatArray,
    omega: FloatArray,
    omega_dot: FloatArray,
    mount: FloatArray,
    gravity_base: FloatArray,
    point_m: FloatArray,
) -> FloatArray:
    """Specific force (m/s²) in the sensor frame at ``point_m`` of the innermost table frame.

    :param r_inner: (n, 3, 3) innermost attitude.
    :param omega: (n, 3) angular velocity, base coordinates (rad/s).
    :param omega_dot: (n, 3) angular acceleration, base coordinates (rad/s²).
    :param mount: (3, 3) rotation sensor frame -> innermost table frame.
    :param gravity_base: (n, 3) or (3,) reaction to gravity in base coordinates (m/s²).
    :param point_m: (3,) position in the innermost table frame (m).
    :returns: (n, 3) f = Mᵀ·R_innerᵀ·(g + ω̇×p + ω×(ω×p)), p = R_inner·point.
    """
    p = r_inner @ np.asarray(point_m, dtype=float)
    accel = np.cross(omega_dot, p) + np.cross(omega, np.cross(omega, p))
    total = accel + gravity_base
    in_inner = np.einsum("nji,nj->ni", r_inner, total)
    f: FloatArray = in_inner @ np.asarray(mount, dtype=float)
    return f
