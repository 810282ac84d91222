"""A channel's own excess ε_c² as a REML variance component of ``noise_reml.fit_noise``."""

from __future__ import annotations

import numpy as np

from bench.estimation.noise_reml import fit_noise
from bench.estimation.slow_noise import NoiseParams, without_excess

SIGMA = 1e-5
M = 200


def _windows(seed: int, excess_sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(X, z, V, mid_s): M windows in random directions, white noise SIGMA, an excess of
    ``excess_sigma`` on channel 0 alone, independent from window to window."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(M, 3))
    f = 9.81 * d / np.linalg.norm(d, axis=1, keepdims=True)
    X = np.zeros((3 * M, 12))
    for i in range(3):
        X[i::3, i] = 1.0
        X[i::3, 3 + 3 * i : 6 + 3 * i] = f
    K = np.diag([0.0177, 0.0175, 0.0178])
    y = 1.5 + f @ K.T + rng.normal(0.0, SIGMA, (M, 3))
    y[:, 0] += rng.normal(0.0, excess_sigma, M)
    V = np.broadcast_to(np.eye(3) * SIGMA**2, (M, 3, 3)).copy()
    return X, y.reshape(-1), V, np.arange(M) * 40.0


def test_reml_recovers_a_channels_own_excess_within_its_sampling_error() -> None:
    """ε = 3 σ on channel 0: ε̂² within 4 standard errors of 9 σ², the standard error of a
    variance from M residuals √(2/M) (σ² + ε²) = σ²; the other channels, asked for none, have none."""
    X, z, V, mid = _windows(1, 3.0 * SIGMA)
    noise, _ = fit_noise(X, z, V, mid, excess_start=np.array([SIGMA**2, 0.0, 0.0]))
    assert noise.excess_channels == (0,) and noise.excess_var is not None
    assert abs(noise.excess_var[0] - 9.0 * SIGMA**2) < 4.0 * SIGMA**2
    assert noise.excess_var[1] == 0.0 and noise.excess_var[2] == 0.0


def test_an_excess_started_where_there_is_none_goes_to_zero_and_is_carried_by_init() -> None:
    """No excess in the data, started at (5 σ)²: REML takes it below its sampling error σ²; a fit
    from that estimate as ``init`` keeps the channel as a free parameter, ``without_excess`` drops it."""
    X, z, V, mid = _windows(2, 0.0)
    noise, _ = fit_noise(X, z, V, mid, excess_start=np.array([25.0 * SIGMA**2, 0.0, 0.0]))
    assert noise.excess_var is not None and noise.excess_var[0] < SIGMA**2
    again, _ = fit_noise(X, z, V, mid, init=noise, near_init=True)
    assert again.excess_channels == (0,)
    plain, _ = fit_noise(X, z, V, mid, init=without_excess(noise), near_init=True)
    assert plain.excess_channels == () and plain.excess_var is None
    assert plain.n_free == noise.n_free - 1


def test_no_excess_asked_for_leaves_the_noise_as_it_was() -> None:
    X, z, V, mid = _windows(3, 3.0 * SIGMA)
    noise, _ = fit_noise(X, z, V, mid, init=NoiseParams(tau2=np.full(3, SIGMA**2)))
    assert noise.excess_var is None and noise.excess_channels == ()
