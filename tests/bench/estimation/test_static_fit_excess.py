"""Static fit: a between-window excess as large as the windows' own noise reaches the sigmas.

Window means of the twelve static-12 poses are drawn directly (no samples): y_w = b + K f_w
+ e_w, e_w with the windows' own variance σ² plus an independent excess τ² = σ² per channel
(what motion inside windows or a wander between them adds), and the fit is told σ² only.
The truth is known, so honest z-scores of K and the bias have RMS 1: over 120 sessions
(1080 K and 360 bias z, correlated within a session) such an RMS lies within 0.8–1.25 with
a wide margin (1.01 and 1.02 when written; 1.10 and 1.16 with the excess gated at the 95 %
point of χ²); a fit that counted σ² alone would give about √2 (1.41).
"""

from __future__ import annotations

import numpy as np

from bench.estimation.static_fit import fit_static
from drivers.sim.offline import static12_poses_deg

G = 9.80665


def _static12_f() -> np.ndarray:
    """(12, 3) specific force of the static-12 poses in the sensor frame (m/s²)."""
    _, m, i = np.deg2rad(static12_poses_deg()).T
    return G * np.column_stack([np.sin(m) * np.sin(i), np.sin(m) * np.cos(i), np.cos(m)])


def test_excess_equal_to_own_noise_is_carried_into_the_sigmas() -> None:
    rng = np.random.default_rng(2101)
    f = _static12_f()
    sigma = 3e-6
    V = np.tile(np.eye(3) * sigma**2, (12, 1, 1))
    z_k, z_b = [], []
    for _ in range(120):
        K = np.diag(0.0177 * (1 + 0.01 * rng.standard_normal(3))) + 2e-5 * rng.standard_normal((3, 3))
        b = 1.5 + 1e-3 * rng.standard_normal(3)
        e = sigma * rng.standard_normal((12, 3)) + sigma * rng.standard_normal((12, 3))
        fit = fit_static(f, b + f @ K.T + e, V)
        z_k.append(((fit.K - K) / fit.K_sigma).ravel())
        z_b.append((fit.bias - b) / fit.bias_sigma)
    rms_k = float(np.sqrt(np.mean(np.square(z_k))))
    rms_b = float(np.sqrt(np.mean(np.square(z_b))))
    assert 0.8 <= rms_k <= 1.25, f"K z RMS {rms_k:.3f}"
    assert 0.8 <= rms_b <= 1.25, f"bias z RMS {rms_b:.3f}"
