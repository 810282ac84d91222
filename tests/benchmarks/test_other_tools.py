"""The other tools' models reproduced in ``benchmarks/other_tools.py``, on synthetic window
means made with calbench's model y = b + K f (known b, K): each recovers them exactly."""

from __future__ import annotations

import numpy as np

from benchmarks.other_tools import ferraris_closed_form, imu_tk_fit

G = 9.81744


def test_imu_tk_model_returns_calbench_bias_and_lower_triangular_scale() -> None:
    """IMU-TK's a = T diag(k) (y − b) and calbench's y = b + L f describe the same |f| = g data;
    the fit written as L is the L that made the data (K Kᵀ = L Lᵀ fixes a lower-triangular L)."""
    rng = np.random.default_rng(11)
    b = np.array([33124.0, 33275.0, 32364.0])
    L = np.array([[414.4, 0.0, 0.0], [1.5, 412.1, 0.0], [3.8, 8.8, 414.5]])
    f = rng.standard_normal((30, 3))
    f *= G / np.linalg.norm(f, axis=1, keepdims=True)
    y = b + f @ L.T
    b_fit, L_fit = imu_tk_fit(y, G)
    np.testing.assert_allclose(b_fit, b, rtol=0, atol=1e-4)
    np.testing.assert_allclose(L_fit, L, rtol=0, atol=1e-5)


def test_ferraris_closed_form_on_six_axis_poses() -> None:
    b = np.array([-6.0, -48.3, -29.0])
    K = np.array([[208.5, 1.5, -2.3], [-1.7, 207.9, 4.9], [4.6, -2.3, 214.7]])
    poses = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    y = b + (G * poses) @ K.T  # x_p, x_a, y_p, y_a, z_p, z_a
    b_fit, K_fit = ferraris_closed_form(y, G)
    np.testing.assert_allclose(b_fit, b, atol=1e-9)
    np.testing.assert_allclose(K_fit, K, atol=1e-12)
