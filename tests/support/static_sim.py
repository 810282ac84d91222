"""Independent sample-level simulation of static multi-position runs for the fit tests.

Orientations come from scipy's Rotation (not bench.kinematics); noise is generated per
sample (white + Gauss-Markov processes that run through the whole recording, moves
included), then each window is cut out of the sample stream. Used only by tests.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

G_LOCAL = 9.81535
G0 = 9.80665

# Middle/inner angles of a 12-position tumble (degrees): each axis up and down plus six
# orientations between them.
TUMBLE_12_DEG = np.array(
    [[0, 0], [180, 0], [90, 0], [90, 90], [90, 180], [90, 270],
     [-90, 45], [-90, 135], [45, 45], [135, 225], [45, 300], [135, 120]],
    dtype=float,
)  # fmt: skip


def tumble_specific_force(angles_deg: np.ndarray = TUMBLE_12_DEG, g: float = G_LOCAL) -> np.ndarray:
    """(m, 3) specific force in the sensor frame for middle (x) / inner (z) table angles."""
    R = Rotation.from_euler("XZ", angles_deg, degrees=True)  # intrinsic: R = Rx(a) Rz(b)
    return R.inv().apply(np.array([0.0, 0.0, g]))


@dataclass
class SimRun:
    f: np.ndarray  # (m, 3) true specific force per window (m/s²)
    f_nominal: np.ndarray  # (m, 3) what the fit is told (pose errors make them differ)
    windows: list[np.ndarray]  # m arrays (n, 3) raw samples (V)
    bias_true: np.ndarray  # (3,) fixed bias + run mean of the wander over the windows
    K_true: np.ndarray  # (3, 3) V per m/s²


def random_truth(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A plausible ADXL-like triad in volts: bias ≈ 1.5 V, K ≈ 0.0176 V/(m/s²) ± 2 %, 1e-4 cross terms."""
    b = 1.5 + rng.normal(0, 0.005, 3)
    K = np.diag(0.0176 * (1 + rng.normal(0, 0.02, 3))) + rng.normal(0, 1e-4, (3, 3)) * (1 - np.eye(3))
    return b, K


def gauss_markov(rng: np.random.Generator, n: int, sigma: float, tau_s: float, fs: float) -> np.ndarray:
    """(n, 3) stationary first-order Gauss-Markov process, std sigma, correlation time tau_s."""
    phi = np.exp(-1.0 / (tau_s * fs))
    e = rng.normal(0, sigma * np.sqrt(1 - phi**2), (n, 3))
    e[0] = rng.normal(0, sigma, 3)
    return _ar1(e, phi)


def _ar1(e: np.ndarray, phi: float) -> np.ndarray:
    zi = np.zeros((1, e.shape[1]))
    out, _ = lfilter([1.0], [1.0, -phi], e[1:], axis=0, zi=phi * e[:1] + zi)
    return np.vstack([e[:1], out])


def simulate_run(
    rng: np.random.Generator,
    *,
    f: np.ndarray | None = None,
    dwell_s: float = 30.0,
    move_s: float = 4.0,
    fs: float = 100.0,
    white_m_s2: float = 2e-3 * G0,
    fast_gm: tuple[float, float] = (1e-3 * G0, 0.05),
    slow_gm: tuple[float, float] = (40e-6 * G0, 200.0),
    pose_error_rad: float = 0.0,
) -> SimRun:
    """Simulate one static run at sample level; noise in specific force (m/s²) then through K."""
    f_nom = tumble_specific_force() if f is None else f
    m = f_nom.shape[0]
    b, K = random_truth(rng)
    if pose_error_rad > 0:
        rot = Rotation.from_rotvec(rng.normal(0, pose_error_rad, (m, 3)))
        f_true = rot.apply(f_nom)
    else:
        f_true = f_nom.copy()
    n_dwell, n_move = int(dwell_s * fs), int(move_s * fs)
    n_total = m * (n_dwell + n_move)
    noise = rng.normal(0, white_m_s2, (n_total, 3))
    wander = np.zeros((n_total, 3))
    if fast_gm[0] > 0:
        noise += gauss_markov(rng, n_total, fast_gm[0], fast_gm[1], fs)
    if slow_gm[0] > 0:
        wander = gauss_markov(rng, n_total, slow_gm[0], slow_gm[1], fs)
    windows, wander_in = [], []
    for w in range(m):
        s = w * (n_dwell + n_move) + n_move
        sl = slice(s, s + n_dwell)
        windows.append(b + (f_true[w] + noise[sl] + wander[sl]) @ K.T)
        wander_in.append(wander[sl])
    bias_true = b + np.concatenate(wander_in).mean(axis=0) @ K.T
    return SimRun(f=f_true, f_nominal=f_nom, windows=windows, bias_true=bias_true, K_true=K)
