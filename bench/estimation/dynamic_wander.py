"""Slow bias wander between the blocks of a moving-table recording, and what it costs θ̂.

The dynamic batch fit (``dynamic_batch``) weighs every sample by its white noise. A slow
wander s(t) of each channel (first-order Gauss–Markov, level τ_c, correlation time T_c) adds
to the residuals a part that is nearly constant over a block of the recording and correlated
between blocks. Where the regressors are constant for a long stretch (a rate table's poses:
gravity is fixed in the sensor frame while the table turns about the vertical), the fit
absorbs most of that wander into bias and K, and the score sandwich, which only sees the
residuals, cannot find it again: with the bench's six rate-table poses and a 40 µg / 200 s
wander the K z-scores of a 28-minute run had an RMS of 1.5 (``benchmarks/study_sigmas_dynamic.py``).

Here the wander is estimated from the block means, with the design that absorbs it:

    z_b = X_b δ + s_b + ε_b,   Cov(ε_b) = diag(σ_c² / n_b),
    Cov(s_b, s_b') = diag(τ_c²) · exp(−|t_b − t_b'| / T_c)

z_b (3,) the block mean of the residuals, X_b (3, p) the block mean of the Jacobian, n_b its
samples, σ_c the fit's residual standard deviation. τ_c² and T_c come from REML
(``noise_reml.fit_noise``: Harville 1977; the T_c grid of ``static_wander``), and the
correlated wander is kept when it beats independent block excesses by the same gate as the
static fit (2Δℓ > 3.84); otherwise the independent excess (T_c = 0) is used, an estimated
extra variance per block. The WLS estimate's error from the wander is, to first order,

    θ̂ − θ = H⁻¹ Σ_b n_b X_bᵀ W s_b,   Cov = H⁻¹ [Σ_c τ_c² w_c² M_c P M_cᵀ] H⁻¹,

M_c (p, n_b) the columns n_b X_b[c, :], P the exponential correlation of the block times,
W = diag(w_c) the fit's weights. Because s(t) is the wander about the unit's long-run bias,
this covariance describes the error against the long-run bias, not the run's mean.

Against the run's mean bias b_c + s̄_c (s̄_c = Σ_b n_b s_b,c / N, N the fitted samples) the
bias row c of the map loses the run's mean: G_c = H⁻¹ M_c w_c, G'_c = G_c − e_c (n_b / N)ᵀ,

    Cov_run = Σ_c τ_c² G'_c P G'_cᵀ   (``cov_run_mean``; rows and columns of K as in ``cov``),

zero for a bias-only fit, whose estimate is the run's mean itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.noise_reml import fit_noise
from bench.estimation.slow_noise import NoiseParams, correlation
from bench.estimation.static_wander import correlation_time_grid

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class BlockWander:
    """REML wander of the blocks and its covariance of θ̂.

    :param noise: τ² (3,) channel units², T_c (s; 0: independent excess per block).
    :param lr: 2Δℓ_REML of the correlated wander over independent block excesses.
    :param cov: (p, p) the wander's contribution to Cov(θ̂), the bias against the long-run bias.
    :param cov_run_mean: (p, p) the same with the bias against the run's mean bias (module
        docstring); the bias parameters are θ's first three, in channel order.
    """

    noise: NoiseParams
    lr: float
    cov: FloatArray
    cov_run_mean: FloatArray

    @property
    def correlated(self) -> bool:
        """The wander is correlated between blocks (T_c > 0) and has a level."""
        return self.noise.corr_time_s > 0 and bool(np.any(self.noise.tau2 > 0))


def fit_block_wander(
    j_sum: FloatArray,
    e_sum: FloatArray,
    counts: FloatArray,
    mid_s: FloatArray,
    noise_sigma: FloatArray,
    h_inv: FloatArray,
    channel_gain: FloatArray | None = None,
) -> BlockWander | None:
    """The block wander of the module docstring; ``None`` with fewer than 8 blocks.

    :param j_sum: (n_b, 3, p) Σ J_t over each block (unweighted).
    :param e_sum: (n_b, 3) Σ residual over each block (channel units).
    :param counts: (n_b,) samples per block (> 0).
    :param mid_s: (n_b,) block mid times (s).
    :param noise_sigma: (3,) the fit's residual standard deviation per channel; weights 1/σ².
    :param h_inv: (p, p) H⁻¹ of the weighted fit.
    :param channel_gain: (3,) channel units per m/s² (row norms of K): one wander level in
        m/s² shared by the channels, scaled by it; ``None``: a level per channel.
    """
    nb, _, p = j_sum.shape
    if nb < 8:
        return None
    n = counts[:, None]
    X = (j_sum / n[:, :, None]).reshape(3 * nb, p)
    z = (e_sum / n).reshape(-1)
    V = np.einsum("bc,cd->bcd", noise_sigma[None, :] ** 2 / n, np.eye(3))
    grid = correlation_time_grid(mid_s)
    n0, f0 = fit_noise(X, z, V, mid_s, corr_times_s=[0.0], channel_gain=channel_gain)
    noise, lr = n0, 0.0
    if grid:
        n1, f1 = fit_noise(
            X, z, V, mid_s, corr_times_s=grid, refine_corr_time=True, channel_gain=channel_gain
        )
        lr = 2.0 * (f1.loglik_reml - f0.loglik_reml)
        if lr > 0.0 and np.any(n1.tau2 > 0):
            noise = n1
    P = correlation(mid_s, noise.corr_time_s)
    w = 1.0 / noise_sigma**2
    cov, cov_run = np.zeros((p, p)), np.zeros((p, p))
    share = counts / counts.sum()
    for c in range(3):
        if noise.tau2[c] <= 0:
            continue
        G = h_inv @ (j_sum[:, c, :] * w[c]).T  # (p, n_b): H⁻¹ Σ_{t∈b} J_t[c, :]ᵀ w_c
        cov += noise.tau2[c] * (G @ P @ G.T)
        G[c] -= share  # against the run's mean: b_c + Σ_b (n_b / N) s_b,c
        cov_run += noise.tau2[c] * (G @ P @ G.T)
    return BlockWander(
        noise=noise, lr=float(lr), cov=0.5 * (cov + cov.T), cov_run_mean=0.5 * (cov_run + cov_run.T)
    )
