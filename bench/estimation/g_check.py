"""The |g| check of a calibration: corrected specific-force magnitude against local gravity.

For each static window w the corrected specific force is f̂_w = K⁻¹ (ȳ_w − b) and its
error e_w = |f̂_w| − g_local. A good calibration leaves mean(e) ≈ 0 and a scatter
std(e) at the noise of the window means (the tumble-test paper's table: ~1e-8 m/s² mean,
3e-4 m/s² scatter after correction, 0.06–0.21 m/s² before).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class GCheck:
    """|g| check over the windows of one run.

    :param magnitude_m_s2: (m,) |f̂_w| (m/s²).
    :param error_m_s2: (m,) |f̂_w| − g_local (m/s²).
    :param mean_error_m_s2: mean of ``error_m_s2``.
    :param std_m_s2: sample standard deviation of ``error_m_s2`` (ddof = 1; 0 for one window).
    :param rms_m_s2: root mean square of ``error_m_s2``.
    """

    magnitude_m_s2: FloatArray
    error_m_s2: FloatArray
    mean_error_m_s2: float
    std_m_s2: float
    rms_m_s2: float


def correct(y: FloatArray, bias: FloatArray, K: FloatArray) -> FloatArray:
    """Corrected specific force f̂ = K⁻¹ (y − b).

    :param y: (m, 3) raw readings (channel units).
    :param bias: (3,) b (channel units).
    :param K: (3, 3) channel unit per m/s².
    :returns: (m, 3) specific force (m/s²).
    :raises ValueError: K singular.
    """
    K = np.asarray(K, dtype=float)
    if not np.all(np.isfinite(K)) or abs(np.linalg.det(K)) < 1e-12 * np.linalg.norm(K) ** 3:
        raise ValueError(f"scale matrix K is singular or not finite: {K.tolist()}")
    d = np.atleast_2d(np.asarray(y, dtype=float)) - np.asarray(bias, dtype=float)
    return np.linalg.solve(K, d.T).T


def g_check(f_hat_m_s2: FloatArray, g_local_m_s2: float) -> GCheck:
    """|g| check of corrected (or nominally scaled) specific forces.

    :param f_hat_m_s2: (m, 3) specific force per window (m/s²).
    :param g_local_m_s2: local gravity (m/s²).
    :returns: :class:`GCheck`.
    """
    f = np.atleast_2d(np.asarray(f_hat_m_s2, dtype=float))
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] == 0:
        raise ValueError(f"specific forces must be (m, 3) with m >= 1, got {f.shape}")
    if not (np.isfinite(g_local_m_s2) and g_local_m_s2 > 0):
        raise ValueError(f"g_local_m_s2 must be positive and finite, got {g_local_m_s2}")
    mag = np.linalg.norm(f, axis=1)
    err = mag - g_local_m_s2
    std = float(err.std(ddof=1)) if err.size > 1 else 0.0
    return GCheck(
        magnitude_m_s2=mag,
        error_m_s2=err,
        mean_error_m_s2=float(err.mean()),
        std_m_s2=std,
        rms_m_s2=float(np.sqrt(np.mean(err**2))),
    )
