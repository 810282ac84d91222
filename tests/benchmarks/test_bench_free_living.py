"""The free-living recording of ``benchmarks/bench_free_living``: no table, no segments, still
periods found by the reader, and the simulated unit recovered by the orientation-free fit."""

from __future__ import annotations

import numpy as np

from bench.calibration import calibrate_recording
from bench.calibration.windows import choose_windows
from benchmarks.bench_free_living import B_TRUE, K_TRUE, RATE_HZ, free_living_recording


def test_a_quarter_hour_is_calibrated_orientation_free_to_the_simulated_unit() -> None:
    rec = free_living_recording(0.25, seed=3)
    assert rec.sidecar.table is None and rec.sidecar.segments is None and rec.table_deg is None
    assert rec.n_samples == round(0.25 * 3600 * RATE_HZ)
    # about one still period per 21 s (8 s still, 7 s moving, log-normal medians): 40 or so
    m = len(choose_windows(rec).used)
    assert 20 <= m <= 70, m
    fit = calibrate_recording(rec)
    g = rec.sidecar.g_local_m_s2
    # offsets: B_TRUE at 30 °C; in 15 min the temperature moves by < 0.25 °C (< 1.3e-4 g at
    # 5e-4 g/°C) and the wander by about 1e-4 g; the fit's sigma is about 5e-5 g
    assert np.all(fit.bias_sigma < 1e-4)
    np.testing.assert_allclose(fit.bias, B_TRUE, atol=4e-4)
    # the scalar fit knows K only up to a rotation: K Kᵀ (g per g) is what it recovers
    assert np.all(fit.K_sigma * g < 2e-4)
    np.testing.assert_allclose((fit.K @ fit.K.T) * g**2, K_TRUE @ K_TRUE.T, atol=6e-4)
