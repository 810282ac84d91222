"""An independent simulator and every-sample fit of a planned procedure, for the planning studies.

Written from the physics, not from calbench's simulator (``drivers.sim``) nor the planner's
trajectory model (``bench.planning.trajectory``), so that a prediction checked on both is not
checked against its own assumptions:

- **Kinematics**: the angles (outer, middle, inner) of R = Rz(outer)·Rx(middle)·Rz(inner)
  (``scipy.spatial.transform.Rotation``, intrinsic "ZXZ") move on quintic minimum-jerk profiles
  q(t) = q₀ + s(u)·Δq, s = 10u³ − 15u⁴ + 6u⁵, u = t/T, each move as long as the slowest axis's
  trapezoid on the simulator's limits (200°/s, 200°/s²); rates and accelerations are the
  profile's exact derivatives (s′ = 30u² − 60u³ + 30u⁴, s″ = 60u − 180u² + 120u³).
- **Angular velocity and acceleration** (base frame), from the chain of axes: with e_z, e_x the
  base axes, a₂ = Rz(outer)·e_x, a₃ = Rz(outer)·Rx(middle)·e_z and ω₁₂ = q̇₁e_z + q̇₂a₂ the
  rate of the middle frame,

      ω  = q̇₁e_z + q̇₂a₂ + q̇₃a₃,
      ω̇  = q̈₁e_z + q̈₂a₂ + q̇₂(q̇₁e_z × a₂) + q̈₃a₃ + q̇₃(ω₁₂ × a₃)

  (a vector fixed in a frame turning at Ω changes at Ω × v).
- **Specific force** at a sensor a lever arm r (m, inner-table frame) from the centre, on a base
  tilted by δ = (δ_x, δ_y) (rad; base = Rx(δ_x)·Ry(δ_y) · level):

      f = Rᵀ(ω̇ × ρ + ω × (ω × ρ)) + Rᵀ·Ry(δ_y)ᵀ·Rx(δ_x)ᵀ·[0, 0, g],   ρ = R·r,

  the first term the acceleration of the sensor point, the second the reaction to gravity
  (Earth's rate neglected).
- **Noise**: white, an exact AR(1) Gauss-Markov wander and a random walk per axis.
- **Fit**: least squares of every sample y = b + K·f(r, δ) for b, K, r and δ by variable
  projection (b, K linear given r, δ; r, δ by ``scipy.optimize.least_squares``).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from bench.planning.noise import UnitNoise
from bench.procedures.preview import move_time_s
from bench.procedures.steps import Dwell, MoveTo, Procedure

G0 = 9.80665
RATE_DEG_S = 200.0
ACC_DEG_S2 = 200.0


def quintic_state(proc: Procedure, fs_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(angles deg, rates deg/s, accelerations deg/s²), each (n, 3), of ``proc`` sampled at
    ``fs_hz`` with quintic moves (module docstring); the table starts at the first pose."""
    ang: list[np.ndarray] = []
    rate: list[np.ndarray] = []
    acc: list[np.ndarray] = []

    def hold(pos: np.ndarray, seconds: float) -> None:
        m = round(seconds * fs_hz)
        ang.append(np.repeat(pos[None], m, axis=0))
        rate.append(np.zeros((m, 3)))
        acc.append(np.zeros((m, 3)))

    pos: np.ndarray | None = None
    for step in proc.steps:
        if isinstance(step, MoveTo):
            target = np.asarray(step.angles_deg, dtype=float)
            if pos is not None:
                d = target - pos
                d[[0, 2]] = (d[[0, 2]] + 180.0) % 360.0 - 180.0  # slip rings: the short way
                dur = max(move_time_s(abs(d[a]), RATE_DEG_S, ACC_DEG_S2) for a in range(3))
                u = np.arange(round(dur * fs_hz)) / (dur * fs_hz)
                s = 10 * u**3 - 15 * u**4 + 6 * u**5
                ds = (30 * u**2 - 60 * u**3 + 30 * u**4) / dur
                dds = (60 * u - 180 * u**2 + 120 * u**3) / dur**2
                ang.append(pos + s[:, None] * d)
                rate.append(ds[:, None] * d)
                acc.append(dds[:, None] * d)
                target = pos + d
            pos = target
            hold(pos, step.settle_s)
        elif isinstance(step, Dwell):
            assert pos is not None and step.duration_s is not None
            hold(pos, step.duration_s)
    return np.concatenate(ang), np.concatenate(rate), np.concatenate(acc)


def angular_motion(
    ang_deg: np.ndarray, rate_deg_s: np.ndarray, acc_deg_s2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(ω rad/s, ω̇ rad/s²), each (n, 3) in the base frame, of the inner table (module docstring)."""
    q, qd, qdd = np.radians(ang_deg), np.radians(rate_deg_s), np.radians(acc_deg_s2)
    ez = np.array([0.0, 0.0, 1.0])
    a2 = Rotation.from_euler("Z", q[:, :1]).apply([1.0, 0.0, 0.0])
    a3 = Rotation.from_euler("ZX", q[:, :2]).apply(ez)
    w12 = qd[:, :1] * ez + qd[:, 1:2] * a2
    w = w12 + qd[:, 2:3] * a3
    wd = (
        qdd[:, :1] * ez
        + qdd[:, 1:2] * a2
        + qd[:, 1:2] * np.cross(qd[:, :1] * ez, a2)
        + qdd[:, 2:3] * a3
        + qd[:, 2:3] * np.cross(w12, a3)
    )
    return w, wd


class Motion:
    """A procedure's sampled motion: rotations R (base from sensor) and the lever-arm and
    gravity terms of the specific force (module docstring)."""

    def __init__(self, proc: Procedure, fs_hz: float) -> None:
        ang, rate, acc = quintic_state(proc, fs_hz)
        self.R = Rotation.from_euler("ZXZ", ang, degrees=True)
        w, wd = angular_motion(ang, rate, acc)
        # Rᵀ(ω̇ × ρ + ω × (ω × ρ)) with ρ = R·r is linear in r: column j is the term for r = e_j
        cols = []
        for j in range(3):
            rho = self.R.apply(np.eye(3)[j] * np.ones((len(ang), 1)))
            cols.append(self.R.inv().apply(np.cross(wd, rho) + np.cross(w, np.cross(w, rho))))
        self.lever = np.stack(cols, axis=2)  # (n, 3, 3): ∂f/∂r

    def force(self, r_m: np.ndarray, tilt_rad: np.ndarray) -> np.ndarray:
        """(n, 3) specific force (m/s²) in the sensor frame for lever arm ``r_m`` and base tilt."""
        base = Rotation.from_euler("XY", tilt_rad)  # base frame = Rx(δx)·Ry(δy) · level (intrinsic)
        g_base = base.inv().apply([0.0, 0.0, G0])
        return np.asarray(self.R.inv().apply(g_base) + self.lever @ r_m, dtype=float)


def noise_series(noise: UnitNoise, n: int, fs_hz: float, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) white + AR(1) Gauss-Markov wander + random walk (m/s²)."""
    dt = 1.0 / fs_hz
    e = noise.white_m_s2_rt_hz / np.sqrt(dt) * rng.standard_normal((n, 3))
    if noise.wander_m_s2 > 0:
        a = np.exp(-dt / noise.wander_tau_s)
        w = np.empty((n, 3))
        w[0] = noise.wander_m_s2 * rng.standard_normal(3)
        kick = noise.wander_m_s2 * np.sqrt(1 - a * a) * rng.standard_normal((n, 3))
        for k in range(1, n):
            w[k] = a * w[k - 1] + kick[k]
        e += w
    if noise.random_walk_m_s2_rt_s > 0:
        e += np.cumsum(noise.random_walk_m_s2_rt_s * np.sqrt(dt) * rng.standard_normal((n, 3)), axis=0)
    return e


def fit_every_sample(motion: Motion, y: np.ndarray, nuisance: bool) -> np.ndarray:
    """(3, 3) K of the least squares of every sample (module docstring); ``nuisance``: the lever
    arm and the base tilt are estimated too, else they are taken as zero."""

    def solve(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f = motion.force(p[:3], p[3:])
        x = np.column_stack([np.ones(len(f)), f])
        theta, *_ = np.linalg.lstsq(x, y, rcond=None)  # (4, 3): column i = [b_i, K_i·]
        return theta, (y - x @ theta).ravel()

    p = np.zeros(5)
    if nuisance:
        p = least_squares(lambda v: solve(v)[1], p, x_scale=[0.01, 0.01, 0.01, 1e-3, 1e-3]).x
    theta, _ = solve(p)
    return np.asarray(theta[1:].T, dtype=float)


def k_error(proc: Procedure, noise: UnitNoise, seed: int, fs_hz: float, effects: bool) -> np.ndarray:
    """(3, 3) K error of one independent run of ``proc``; ``effects``: a base tilt of 3′ rms
    (each component 3′/√2) and a 3 cm lever arm in a random direction, both fitted."""
    rng = np.random.default_rng([seed, 2323])
    motion = Motion(proc, fs_hz)
    n = len(motion.lever)
    K = np.eye(3) + 2e-3 * rng.standard_normal((3, 3))
    b = 0.05 * rng.standard_normal(3)
    r, tilt = np.zeros(3), np.zeros(2)
    if effects:
        u = rng.standard_normal(3)
        r = 0.03 * u / np.linalg.norm(u)
        tilt = np.radians(3 / 60) / np.sqrt(2) * rng.standard_normal(2)
    y = b + motion.force(r, tilt) @ K.T + noise_series(noise, n, fs_hz, rng)
    return fit_every_sample(motion, y, effects) - K
