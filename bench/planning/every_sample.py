"""The covariance the every-sample fit reaches on a design's specific-force trajectory.

The dynamic batch fit (``bench.estimation.dynamic_batch``, bias and K) is, per channel i and
near K = I, the ordinary least squares of

    y_i(t) = b_i + K_i·f(t) + e_i(t),   regressors x_t = [1, f(t)ᵀ] (4,),

with one weight per channel, over every sample of the recording, moves included. With noise of
covariance Σ (white + Gauss-Markov wander + random walk, ``bench.planning.noise``) the OLS
estimate has the exact covariance (the sandwich; e.g. Greene, *Econometric Analysis*, §9.2)

    Cov([b_i, K_i·]) = A⁻¹ B A⁻¹,   A = Σ_t x_t x_tᵀ,   B = Σ_{t,s} x_t x_sᵀ Σ(t, s),

the same for the three channels (the same regressors and noise). The white part of B is
σ²·A with σ² = N²·f_s the per-sample variance. The slow part (wander, random walk: correlated
over ≫ 1 s) is constant over a block of ``block_s``, so with S_b = Σ_{t∈b} x_t

    B_slow = Σ_{b,c} S_b S_cᵀ · k(t_b, t_c),   t_b the block's centre,

with the kernels of ``bench.planning.noise`` (B²·e^{−|t−s|/T_c}, K²·min(t, s)) summed in O(blocks)
by recursions (:func:`slow_information`), so a two-hour design costs milliseconds. Unlike the
window fit's prediction this is the estimator's own error, not the GLS bound: the every-sample
fit weights the samples equally.

Nuisance parameters ν (a lever arm r, a base tilt δ: ``bench.planning.trajectory.nuisance_response``)
shared by the three channels join the regressors: channel i's row at t is
x_ti = [e_i, e_i ⊗ f(t), ∂f_i/∂ν(t)] over θ = [b (3), K (9), ν (q)], and with the same noise on
each channel A = Σ_i Σ_t x_ti x_tiᵀ, B = N²f_s·A + Σ_i Σ_{b,c} S_b^i S_c^iᵀ k(t_b, t_c) (S_b^i the
sums of channel i's rows over block b); Cov(θ) = A⁻¹BA⁻¹ as before, and without ν it is the
three channels' 4 × 4 blocks above.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

from bench.planning.information import N_CORE, PredictedUncertainty
from bench.planning.noise import UnitNoise

FloatArray = npt.NDArray[np.float64]

BLOCK_S = 1.0
"""Block over which the slow noise is taken as constant (s)."""


def every_sample_uncertainty(
    t_s: FloatArray,
    f_m_s2: FloatArray,
    noise: UnitNoise,
    block_s: float = BLOCK_S,
    *,
    nuisance: FloatArray | None = None,
) -> PredictedUncertainty:
    """Predicted σ of [b, K] (and the nuisance parameters) of the every-sample fit (module docstring).

    :param t_s: (n,) sample times (s, from the run's start), uniformly spaced.
    :param f_m_s2: (n, 3) specific force at each sample (m/s²).
    :param noise: the unit's noise.
    :param block_s: block of the slow noise (s).
    :param nuisance: (n, 3, q) ∂f/∂ν of nuisance parameters the fit estimates too, or ``None``;
        their σ are the result's ``nuisance``.
    :raises ValueError: shapes disagree, fewer than 2 samples, or the trajectory does not
        identify bias and K (its force does not span three directions) or the nuisance
        parameters beside them.
    """
    t = np.asarray(t_s, dtype=float)
    f = np.asarray(f_m_s2, dtype=float)
    if t.ndim != 1 or f.shape != (len(t), 3) or len(t) < 2:
        raise ValueError(f"trajectory: expected t (n,) and f (n, 3) with n >= 2, got {t.shape} and {f.shape}")
    if nuisance is not None:
        return _with_nuisance(t, f, np.asarray(nuisance, dtype=float), noise, block_s)
    dt = float(t[1] - t[0])
    x = np.column_stack([np.ones(len(t)), f])
    A = x.T @ x
    cond = np.linalg.cond(A)
    if not np.isfinite(cond) or cond > 1e12:
        raise ValueError(f"the trajectory does not identify bias and K (information condition {cond:.2g})")
    B = noise.white_m_s2_rt_hz**2 / dt * A
    if noise.wander_m_s2 > 0 or noise.random_walk_m_s2_rt_s > 0:
        idx, t_b = _blocks(t, block_s)
        B += slow_information(block_sums(x, idx, len(t_b)), t_b, block_s, noise)
    Ai = np.linalg.inv(A)
    cov4 = Ai @ B @ Ai
    cov4 = 0.5 * (cov4 + cov4.T)
    cov = np.zeros((N_CORE, N_CORE))
    for i in range(3):
        rows = [i, 3 + 3 * i, 4 + 3 * i, 5 + 3 * i]
        cov[np.ix_(rows, rows)] = cov4
    sd = np.sqrt(np.diag(cov))
    return PredictedUncertainty(cov, sd[:3].copy(), sd[3:12].reshape(3, 3).copy(), np.zeros(0))


def _with_nuisance(
    t: FloatArray, f: FloatArray, dfdv: FloatArray, noise: UnitNoise, block_s: float
) -> PredictedUncertainty:
    """:func:`every_sample_uncertainty` with nuisance columns ``dfdv`` (n, 3, q) shared by the channels."""
    n, q = len(t), dfdv.shape[2]
    if dfdv.shape != (n, 3, q):
        raise ValueError(f"nuisance: expected (n, 3, q) with n = {n}, got {dfdv.shape}")
    p = N_CORE + q
    dt = float(t[1] - t[0])
    slow = noise.wander_m_s2 > 0 or noise.random_walk_m_s2_rt_s > 0
    if slow:
        idx, t_b = _blocks(t, block_s)
    # channel i's row x_ti is zero but in columns [b_i, K_i·, ν]; its nonzero part z_ti = [1, f, ∂f_i/∂ν]
    # gives A's and B_slow's entries on those columns (both are sums of products of the row's entries)
    A = np.zeros((p, p))
    B_slow = np.zeros((p, p))
    ones = np.ones((n, 1))
    for i in range(3):
        cols = np.ix_(*2 * ([i, 3 + 3 * i, 4 + 3 * i, 5 + 3 * i, *range(N_CORE, p)],))
        z = np.concatenate([ones, f, dfdv[:, i, :]], axis=1)
        A[cols] += z.T @ z
        if slow:
            B_slow[cols] += slow_information(block_sums(z, idx, len(t_b)), t_b, block_s, noise)
    d = np.sqrt(np.diag(A))
    cond = np.linalg.cond(A / np.outer(d, d)) if np.all(d > 0) else np.inf
    if not np.isfinite(cond) or cond > 1e12:
        raise ValueError(
            f"the trajectory does not identify bias, K and the nuisance parameters (condition {cond:.2g})"
        )
    B = noise.white_m_s2_rt_hz**2 / dt * A + B_slow
    Ai = np.linalg.inv(A)
    cov = Ai @ B @ Ai
    cov = 0.5 * (cov + cov.T)
    sd = np.sqrt(np.diag(cov))
    return PredictedUncertainty(
        cov, sd[:3].copy(), sd[3:12].reshape(3, 3).copy(), np.zeros(0), sd[N_CORE:].copy()
    )


def _blocks(t: FloatArray, block_s: float) -> tuple[npt.NDArray[np.int64], FloatArray]:
    """Each sample's block (n,) and the blocks' centres (n_b,) (s)."""
    idx = np.floor((t - t[0]) / block_s).astype(np.int64)
    nb = int(idx[-1]) + 1
    return idx, t[0] + (np.arange(nb) + 0.5) * block_s


def block_sums(x: FloatArray, idx: npt.NDArray[np.int64], n_blocks: int) -> FloatArray:
    """(n_blocks, p) S_b = Σ_{t∈b} x_t of rows x (n, p) in blocks ``idx`` (n,), summed in order."""
    return np.stack(
        [np.bincount(idx, weights=x[:, k], minlength=n_blocks) for k in range(x.shape[1])], axis=1
    )


def slow_information(S: FloatArray, t_b: FloatArray, block_s: float, noise: UnitNoise) -> FloatArray:
    """(p, p) Σ_{b,c} S_b S_cᵀ·k(t_b, t_c) for the wander and random-walk kernels.

    Gauss-Markov, a = e^{−Δ/T_c}: Σ_{b,c} a^{|b−c|} S_b S_cᵀ = Σ_b (S_b S_bᵀ + S_b G_bᵀ + G_b S_bᵀ)
    with G_b = Σ_{c<b} a^{b−c} S_c = a·(G_{b−1} + S_{b−1}). Random walk: min(t_b, t_c) =
    ∫₀^∞ 1[t_b > u]·1[t_c > u] du, so the sum is Σ_b (t_b − t_{b−1})·R_b R_bᵀ with R_b = Σ_{c≥b} S_c
    (t_{−1} = 0).

    :param S: (n_b, p) regressor sums per block; :param t_b: (n_b,) block centres (s).
    """
    out = np.zeros((S.shape[1], S.shape[1]))
    if noise.wander_m_s2 > 0:
        a = float(np.exp(-block_s / noise.wander_tau_s))
        G = lfilter([0.0, a], [1.0, -a], S, axis=0)  # G_b = a·G_{b−1} + a·S_{b−1}, G_0 = 0
        cross = S.T @ G
        out += noise.wander_m_s2**2 * (S.T @ S + cross + cross.T)
    if noise.random_walk_m_s2_rt_s > 0:
        R = np.cumsum(S[::-1], axis=0)[::-1]
        du = np.diff(np.concatenate([[0.0], t_b]))
        out += noise.random_walk_m_s2_rt_s**2 * (R.T * du) @ R
    return out
