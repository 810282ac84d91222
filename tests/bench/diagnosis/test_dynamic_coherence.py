"""The von Neumann test of moving block means (``dynamic_coherence``): exact moments, its level on
independent block means, its power on a step, and a moving recording with a concealed step."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import binom

from bench.diagnosis.dynamic_coherence import block_coherence, trend_basis, von_neumann_moments
from bench.diagnosis.thresholds import THRESHOLDS


def _nuisance(rng: np.random.Generator, nb: int) -> np.ndarray:
    return np.column_stack([np.ones(nb), rng.standard_normal((nb, 3))])


def test_moments_match_a_direct_computation_with_the_dense_projector() -> None:
    rng = np.random.default_rng(3)
    nb = 40
    X = np.column_stack([_nuisance(rng, nb), trend_basis(nb, 3)])
    Q, _ = np.linalg.qr(X)
    D = np.diff(np.eye(nb), axis=0)
    M = np.eye(nb) - Q @ Q.T
    MA = M @ D.T @ D
    m = nb - Q.shape[1]
    mean = np.trace(MA) / m
    var = (np.trace(MA) ** 2 + 2 * np.trace(MA @ MA)) / (m * (m + 2)) - mean**2
    got = von_neumann_moments(Q)
    assert got[0] == pytest.approx(mean, rel=1e-12)
    assert got[1] == pytest.approx(var, rel=1e-10)


def test_the_level_holds_on_independent_block_means_with_a_wander_trend() -> None:
    # 600 draws × 3 channels of independent block means (unequal counts) plus a cubic trend the
    # basis takes out; the lower tail at 0.05 must fire on 0.05 of them: the 1e-4 binomial interval
    rng = np.random.default_rng(11)
    nb, alpha, draws = 120, 0.05, 600
    cnt = rng.integers(60, 101, nb)
    F = _nuisance(rng, nb)
    s = np.linspace(-1, 1, nb)
    fired = 0
    for _ in range(draws):
        b = rng.standard_normal((nb, 3)) / np.sqrt(cnt)[:, None] + 0.3 * np.outer(
            s**3 - s, rng.standard_normal(3)
        )
        c = block_coherence(b, cnt, F, 3)
        assert c is not None
        fired += int(np.sum(c.p_value < alpha))
    n = 3 * draws
    lo, hi = binom.ppf(1e-4, n, alpha), binom.isf(1e-4, n, alpha)
    assert lo <= fired <= hi


def test_a_step_of_six_block_sigmas_is_found_on_its_channel_only() -> None:
    rng = np.random.default_rng(5)
    nb = 120
    cnt = np.full(nb, 100)
    F = _nuisance(rng, nb)
    hits = 0
    for _ in range(50):
        b = rng.standard_normal((nb, 3)) / 10.0
        b[int(rng.integers(30, 90)) :, 1] += 6.0 / 10.0
        c = block_coherence(b, cnt, F, THRESHOLDS.coherence_trend_degree)
        assert c is not None
        hits += int(c.p_value[1] < THRESHOLDS.unexplained_alpha / 3)
        assert c.p_value[[0, 2]].min() > 1e-5
    # a 6 sigma step at mid-run leaves 0.14·9 ≈ 1.3 white variances beyond the cubic (the share of
    # sign(s) outside P_1, P_3 on [−1, 1]): R falls from 2 to about 0.9, 7 of its sigmas (0.16),
    # where the gate sits 3.4 sigmas down; 45 of 50 leaves room for steps off the middle
    assert hits >= 45


@pytest.mark.slow
def test_a_moving_recording_with_a_concealed_step_is_unexplained_on_that_channel() -> None:
    from bench.calibration.diagnose import diagnose_recording
    from tests.support.diagnose_dynamic_cases import moving_recording

    clean = moving_recording({}, 1001, kind="oscillation")
    assert diagnose_recording(clean).unexplained is None
    y = np.array(clean.accel_raw, dtype=float)
    t = np.asarray(clean.t_s) - clean.t_s[0]
    sig_b = float(np.std(np.diff(y[:, 2])) / np.sqrt(2.0)) / 10.0  # 100 Hz: 100 samples per block
    y[:, 2] += 6.0 * sig_b * (t >= 0.4 * t[-1])
    d = diagnose_recording(replace(clean, accel_raw=y))
    assert d.unexplained is not None
    assert d.unexplained.where.startswith("az:")
