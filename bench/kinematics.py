"""Table kinematics: attitude, angular rate and acceleration, and the specific force a sensor feels.

Pure numpy, SI units (radians, seconds, metres). The conventions are those of
``docs/recording-format.md``: the base frame is fixed to the room with z up; axis 1 is the
outermost; each axis vector ``u_i`` is given in its parent frame at zero angles; the
sensor's attitude (sensor frame -> base frame) is

    R = Rot(u1, θ1) · Rot(u2, θ2) · … · Rot(uN, θN) · M

and an ideal accelerometer reads, in the sensor frame,

    f = Rᵀ · ( [0, 0, g] + ω̇ × p + ω × (ω × p) ),   p = R_inner · lever_arm

with ω the angular velocity of the innermost frame in base coordinates and R_inner the
product without M (Titterton & Weston, *Strapdown Inertial Navigation Technology*,
2nd ed., §3.2 and eq. 3.23 for the transport of a rotating lever arm).

Angular velocity of a serial chain (Craig, *Introduction to Robotics*, eq. 5.45 for
revolute joints): with a_i = R_1 ⋯ R_{i-1} u_i the i-th axis in base coordinates,

    ω = Σ_i θ̇_i a_i,     ω̇ = Σ_i ( θ̈_i a_i + θ̇_i ω_{i-1} × a_i ),

where ω_{i-1} = Σ_{j<i} θ̇_j a_j is the rate of the frame that carries axis i
(ȧ_i = ω_{i-1} × a_i).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

_SAVGOL_WINDOW = 7
_SAVGOL_ORDER = 3
_MAX_DT_JITTER = 0.05


def _angles(angles_rad: npt.ArrayLike, k: int) -> FloatArray:
    q = np.asarray(angles_rad, dtype=float)
    if q.ndim == 1 and k == 1:
        q = q[:, None]
    if q.ndim != 2 or q.shape[1] != k:
        raise ValueError(f"angles have shape {q.shape}, expected (n, {k}) for {k} table axes")
    return q


def _axes(axis_vectors: npt.ArrayLike) -> FloatArray:
    u = np.asarray(axis_vectors, dtype=float)
    if u.ndim != 2 or u.shape[1] != 3 or u.shape[0] < 1:
        raise ValueError(f"axis_vectors have shape {u.shape}, expected (k, 3) with k >= 1")
    norms = np.linalg.norm(u, axis=1)
    if np.any(np.abs(norms - 1.0) > 1e-6):
        raise ValueError(f"axis vectors must be unit length (within 1e-6), lengths are {norms.tolist()}")
    return u


def rot(u: npt.ArrayLike, theta_rad: npt.ArrayLike) -> FloatArray:
    """Right-handed rotation by θ about the unit vector u (Rodrigues' formula).

    R = I cos θ + sin θ [u]× + (1 − cos θ) u uᵀ

    :param u: (3,) unit axis.
    :param theta_rad: (n,) angles (rad); a scalar gives n = 1.
    :returns: (n, 3, 3) rotation matrices.
    """
    uu = np.asarray(u, dtype=float).reshape(3)
    th = np.atleast_1d(np.asarray(theta_rad, dtype=float))
    c, s = np.cos(th)[:, None, None], np.sin(th)[:, None, None]
    ux = np.array([[0.0, -uu[2], uu[1]], [uu[2], 0.0, -uu[0]], [-uu[1], uu[0], 0.0]])
    return np.asarray(c * np.eye(3) + s * ux + (1.0 - c) * np.outer(uu, uu), dtype=float)


def _chain(u: FloatArray, q: FloatArray) -> list[FloatArray]:
    """Partial products P_0 = I, P_i = Rot(u1,θ1)…Rot(ui,θi); list of k+1 arrays (n,3,3)."""
    n = q.shape[0]
    P = [np.broadcast_to(np.eye(3), (n, 3, 3))]
    for i in range(u.shape[0]):
        P.append(P[-1] @ rot(u[i], q[:, i]))
    return P


def inner_attitude(axis_vectors: npt.ArrayLike, angles_rad: npt.ArrayLike) -> FloatArray:
    """R_inner = Rot(u1, θ1)…Rot(uk, θk): innermost table frame -> base frame.

    :param axis_vectors: (k, 3) unit axes, outermost first.
    :param angles_rad: (n, k) axis angles (rad).
    :returns: (n, 3, 3).
    """
    u = _axes(axis_vectors)
    return _chain(u, _angles(angles_rad, u.shape[0]))[-1]


def attitude(axis_vectors: npt.ArrayLike, angles_rad: npt.ArrayLike, mount: npt.ArrayLike) -> FloatArray:
    """Sensor attitude R = Rot(u1, θ1)…Rot(uk, θk)·M (sensor frame -> base frame).

    :param axis_vectors: (k, 3) unit axes, outermost first.
    :param angles_rad: (n, k) axis angles (rad).
    :param mount: (3, 3) mount rotation M (sensor nominal frame -> innermost table frame).
    :returns: (n, 3, 3).
    """
    return np.asarray(inner_attitude(axis_vectors, angles_rad) @ np.asarray(mount, dtype=float).reshape(3, 3))


def static_specific_force(R: npt.ArrayLike, g_local_m_s2: float) -> FloatArray:
    """Specific force at rest, in the sensor frame: f = Rᵀ [0, 0, g].

    :param R: (n, 3, 3) attitudes (sensor -> base).
    :param g_local_m_s2: local gravity magnitude (m/s²).
    :returns: (n, 3) (m/s²); a sensor with z up reads +g on z.
    """
    Rm = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    # Rᵀ e_z is the third row of R.
    return g_local_m_s2 * Rm[:, 2, :]


def _axis_terms(
    axis_vectors: npt.ArrayLike, angles_rad: npt.ArrayLike, rates_rad_s: npt.ArrayLike
) -> tuple[FloatArray, FloatArray, list[FloatArray]]:
    u = _axes(axis_vectors)
    k = u.shape[0]
    q = _angles(angles_rad, k)
    qd = _angles(rates_rad_s, k)
    if qd.shape != q.shape:
        raise ValueError(f"rates have shape {qd.shape}, angles {q.shape}; expected equal")
    P = _chain(u, q)
    a = [P[i] @ u[i] for i in range(k)]  # (n, 3) each: axis i in base coordinates
    return q, qd, a


def angular_velocity(
    axis_vectors: npt.ArrayLike, angles_rad: npt.ArrayLike, rates_rad_s: npt.ArrayLike
) -> FloatArray:
    """ω of the innermost frame in base coordinates: ω = Σ θ̇_i a_i.

    :param axis_vectors: (k, 3) unit axes, outermost first.
    :param angles_rad: (n, k) angles (rad).
    :param rates_rad_s: (n, k) axis rates θ̇ (rad/s).
    :returns: (n, 3) (rad/s).
    """
    _q, qd, a = _axis_terms(axis_vectors, angles_rad, rates_rad_s)
    return sum((qd[:, i, None] * a[i] for i in range(len(a))), np.zeros_like(a[0]))


def angular_acceleration(
    axis_vectors: npt.ArrayLike,
    angles_rad: npt.ArrayLike,
    rates_rad_s: npt.ArrayLike,
    accels_rad_s2: npt.ArrayLike,
) -> FloatArray:
    """ω̇ of the innermost frame in base coordinates: Σ ( θ̈_i a_i + θ̇_i ω_{i-1} × a_i ).

    :param accels_rad_s2: (n, k) axis accelerations θ̈ (rad/s²); other parameters as
        :func:`angular_velocity`.
    :returns: (n, 3) (rad/s²).
    """
    q, qd, a = _axis_terms(axis_vectors, angles_rad, rates_rad_s)
    qdd = _angles(accels_rad_s2, q.shape[1])
    w_parent = np.zeros_like(a[0])
    wdot = np.zeros_like(a[0])
    for i, ai in enumerate(a):
        wdot += qdd[:, i, None] * ai + qd[:, i, None] * np.cross(w_parent, ai)
        w_parent = w_parent + qd[:, i, None] * ai
    return wdot


def specific_force(
    axis_vectors: npt.ArrayLike,
    mount: npt.ArrayLike,
    lever_arm_m: npt.ArrayLike,
    angles_rad: npt.ArrayLike,
    rates_rad_s: npt.ArrayLike,
    accels_rad_s2: npt.ArrayLike,
    g_local_m_s2: float,
) -> FloatArray:
    """Ideal accelerometer reading on a moving table, sensor frame.

    f = Rᵀ ( [0, 0, g] + ω̇ × p + ω × (ω × p) ),  p = R_inner · lever_arm

    :param axis_vectors: (k, 3) unit axes, outermost first.
    :param mount: (3, 3) mount rotation M.
    :param lever_arm_m: (3,) sensor position in the innermost table frame (m).
    :param angles_rad: (n, k) angles (rad), unwrapped or not.
    :param rates_rad_s: (n, k) axis rates (rad/s).
    :param accels_rad_s2: (n, k) axis accelerations (rad/s²).
    :param g_local_m_s2: local gravity (m/s²).
    :returns: (n, 3) specific force (m/s²).
    """
    R_in = inner_attitude(axis_vectors, angles_rad)
    R = R_in @ np.asarray(mount, dtype=float).reshape(3, 3)
    p = R_in @ np.asarray(lever_arm_m, dtype=float).reshape(3)
    w = angular_velocity(axis_vectors, angles_rad, rates_rad_s)
    wd = angular_acceleration(axis_vectors, angles_rad, rates_rad_s, accels_rad_s2)
    f_base = np.cross(wd, p) + np.cross(w, np.cross(w, p))
    f_base[:, 2] += g_local_m_s2
    return np.asarray(np.einsum("nji,nj->ni", R, f_base), dtype=float)


def derivatives(
    t_s: npt.ArrayLike, angles_rad_unwrapped: npt.ArrayLike, *, method: str = "savgol"
) -> tuple[FloatArray, FloatArray]:
    """Rates and accelerations of sampled, unwrapped axis angles.

    ``method="savgol"`` (default): Savitzky–Golay, a cubic fitted over 7 samples and
    differentiated (``scipy.signal.savgol_filter``, ``mode="interp"`` at the ends). It is
    exact for angles that are cubic in time over 7 samples (so for trapezoidal rate
    profiles away from the switching instants, where it spreads a rate corner over
    ±3 samples), and it averages encoder quantisation noise better than a three-point
    difference. It needs uniform sampling: time steps may differ from their median by at
    most 5 %, else a :class:`ValueError` asks for ``method="gradient"``.

    ``method="gradient"``: second-order centred differences on the actual time stamps
    (``numpy.gradient`` with ``edge_order=2``), applied twice for the acceleration; for
    irregular time stamps.

    :param t_s: (n,) strictly increasing time (s), n >= 7 (savgol) or n >= 3.
    :param angles_rad_unwrapped: (n, k) angles (rad), unwrapped (``np.unwrap``) first.
    :returns: (rates (n, k) rad/s, accelerations (n, k) rad/s²).
    """
    t = np.asarray(t_s, dtype=float).reshape(-1)
    q = np.asarray(angles_rad_unwrapped, dtype=float)
    squeeze = q.ndim == 1
    q = q[:, None] if squeeze else q
    if q.ndim != 2 or q.shape[0] != t.shape[0]:
        raise ValueError(f"angles have shape {q.shape}, expected ({t.shape[0]}, k) to match t")
    dt = np.diff(t)
    if t.shape[0] < 3 or np.any(dt <= 0) or not np.all(np.isfinite(t)):
        raise ValueError("t_s must be finite, strictly increasing, with at least 3 samples")
    if method == "savgol":
        from scipy.signal import savgol_filter  # only where rates are differentiated (moving tables)

        h = float(np.median(dt))
        if t.shape[0] < _SAVGOL_WINDOW:
            raise ValueError(f"savgol needs at least {_SAVGOL_WINDOW} samples, got {t.shape[0]}")
        jitter = float(np.max(np.abs(dt - h)) / h)
        if jitter > _MAX_DT_JITTER:
            raise ValueError(
                f"time steps vary by {jitter:.1%} of the median step; savgol assumes uniform "
                'sampling, use method="gradient"'
            )
        rates = savgol_filter(q, _SAVGOL_WINDOW, _SAVGOL_ORDER, deriv=1, delta=h, axis=0, mode="interp")
        accels = savgol_filter(q, _SAVGOL_WINDOW, _SAVGOL_ORDER, deriv=2, delta=h, axis=0, mode="interp")
    elif method == "gradient":
        rates = np.gradient(q, t, axis=0, edge_order=2)
        accels = np.gradient(rates, t, axis=0, edge_order=2)
    else:
        raise ValueError(f'method must be "savgol" or "gradient", got {method!r}')
    if squeeze:
        return rates[:, 0], accels[:, 0]
    return rates, accels
