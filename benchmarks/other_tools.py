"""Other tools' calibration models, written here to compare calbench with them on the same
window means (``benchmarks.real_recordings``): IMU-TK's accelerometer model and static-interval
detector (Tedaldi, Pretto, Menegatti, ICRA 2014; imu_tk src/calibration.cpp, src/filters.cpp)
and Ferraris' six-position closed form (Ferraris et al. 1995; imucal's equations 19-23)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from bench.recording import Segment


def imu_tk_fit(y: np.ndarray, g: float) -> tuple[np.ndarray, np.ndarray]:
    """IMU-TK's accelerometer model on window means y (m, 3): bias (3,) and L (3, 3).

    a = T diag(k) (y − b), T = [[1, −α_yz, α_zy], [0, 1, −α_zx], [0, 0, 1]]; least squares of
    g − |a| over the windows (IMU-TK, src/calibration.cpp). Returns b and the lower-triangular
    L with L Lᵀ = (MᵀM)⁻¹, M = T diag(k): the model calbench fits, written its way.
    """

    def tk(p: np.ndarray) -> np.ndarray:
        T = np.array([[1.0, -p[0], p[1]], [0.0, 1.0, -p[2]], [0.0, 0.0, 1.0]])
        return T @ np.diag(p[3:6])

    def resid(p: np.ndarray) -> np.ndarray:
        return g - np.linalg.norm((y - p[6:9]) @ tk(p).T, axis=1)

    x0 = np.r_[0.0, 0.0, 0.0, np.full(3, g / 4000.0), np.full(3, 32768.0)]
    p = least_squares(resid, x0, x_scale=np.r_[1e-2, 1e-2, 1e-2, 1e-5, 1e-5, 1e-5, 10, 10, 10]).x
    M = tk(p)
    return p[6:9], np.linalg.cholesky(np.linalg.inv(M.T @ M))


def imu_tk_intervals(t_s: np.ndarray, y: np.ndarray, k: float = 6.0, init_s: float = 50.0) -> list[Segment]:
    """IMU-TK's static-interval detector (src/filters.cpp ``staticIntervalsDetector``): the
    norm of the per-axis variance over a centred 101-sample window, below k times that of the
    first ``init_s`` seconds; intervals longer than 1 s (data README, k = 6)."""
    half = 50
    c1 = np.vstack([np.zeros((1, 3)), np.cumsum(y - y.mean(axis=0), axis=0)])
    c2 = np.vstack([np.zeros((1, 3)), np.cumsum((y - y.mean(axis=0)) ** 2, axis=0)])
    n = y.shape[0]
    lo = np.clip(np.arange(n) - half, 0, n)
    hi = np.clip(np.arange(n) + half + 1, 0, n)
    cnt = (hi - lo)[:, None]
    mean = (c1[hi] - c1[lo]) / cnt
    var = (c2[hi] - c2[lo]) / cnt - mean**2
    init = np.linalg.norm(np.var(y[t_s - t_s[0] <= init_s], axis=0))
    still = np.linalg.norm(var, axis=1) < k * init
    edges = np.flatnonzero(np.diff(np.r_[0, still.astype(int), 0]))
    segs = []
    for a, b in zip(edges[0::2], edges[1::2], strict=True):
        if t_s[b - 1] - t_s[a] > 1.0:
            segs.append(
                Segment(start_s=float(t_s[a]), end_s=float(t_s[b - 1]), label=f"i{len(segs) + 1:02d}")
            )
    return segs


def ferraris_closed_form(y: np.ndarray, g: float) -> tuple[np.ndarray, np.ndarray]:
    """Ferraris et al. (1995) / imucal eqs. 19-23 on the six pose means x_p, x_a, … z_a (6, 3):
    bias = diag(u⁺ + u⁻) / 2, K = (u⁺ − u⁻) / (2 g) with columns the +x, +y, +z poses."""
    up, un = y[0::2].T, y[1::2].T
    return np.diag(up + un) / 2, (up - un) / (2 * g)
