"""Batch nonlinear least squares of the dynamic model over a whole recording, with honest covariance.

Model: ``dynamic_model`` (raw = h(θ; motion) + e). Estimator: weighted Gauss-Newton with
Levenberg–Marquardt damping (Nocedal & Wright, *Numerical Optimization*, 2nd ed., §10.3),

    (H + λ·diag H) Δ = Jᵀ W e,    H = Jᵀ W J,    W = diag(1/σ_c²) per channel c,

accumulated over chunks of samples so that a 10-minute 1 kHz recording never holds its
Jacobian in memory. σ_c starts from a robust white-noise estimate (MAD of the second
difference of the raw samples, σ² = Var(Δ²y)/6) and is replaced by the residual standard
deviation once the fit has converged; the fit then continues to convergence.

Covariance. At 100 Hz–1 kHz the residuals are not white (the sensor's bias wander, the
unmodelled remainder), and (Jᵀ W J)⁻¹ would then be too small. The reported covariance is
the sandwich (heteroscedasticity-and-autocorrelation-consistent, Newey & West,
Econometrica 55 (1987) 703) built on the scores s_t = J_tᵀ W e_t summed over consecutive
blocks of ``block_s`` seconds (default: the recording split into ``TARGET_BLOCKS`` blocks,
at least ``BLOCK_S`` long, so that a block outlasts the correlation of slow noise such as a
200-s bias wander in a 40-minute recording while enough blocks remain to estimate Ŝ):

    Ŝ = Σ_b s_b s_bᵀ + Σ_{k=1..L} (1 − k/(L+1)) Σ_b (s_b s_{b+k}ᵀ + s_{b+k} s_bᵀ),
    Cov(θ̂) = H⁻¹ Ŝ H⁻¹ · n_b / (n_b − p)

with n_b blocks and L = ``NW_LAGS``. It reduces to H⁻¹ for white residuals and grows by
the integrated autocorrelation of each parameter's own score, so a parameter driven by
a fast regressor is not penalised for slow noise that only the bias sees. With few
effectively independent blocks the sandwich scatters low as often as high, so each
parameter's variance is taken as the larger of the two, with the correlations of
(Jᵀ W J)⁻¹: Cov = C·(Jᵀ W J)⁻¹·C, C = diag(max(1, sandwich_ii / white_ii)^½). Noise slower
than the whole recording cannot be told from the bias by any estimator of one run; it is
part of "the bias this run saw".

The sandwich sees only the residuals; a slow wander that the fit absorbed into bias and K
(long stretches of constant regressors: a rate table's poses) is estimated separately from
the block means of the residuals (``dynamic_wander``, ``WANDER_BLOCKS`` blocks) and its
covariance added to the white bound before the comparison with the sandwich:
Cov = C·(H⁻¹ + Cov_wander)·C. With a correlated wander found the bias sigma describes the
unit's long-run bias (``bias_reference``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from bench.estimation.dynamic_model import ModelSpec, initial_theta, predict, specific_force
from bench.estimation.dynamic_wander import BlockWander, fit_block_wander
from bench.estimation.motion_data import MotionData
from bench.estimation.observability import check_information

FloatArray = npt.NDArray[np.float64]

CHUNK_SAMPLES = 20_000
BLOCK_S = 1.0
TARGET_BLOCKS = 50
WANDER_BLOCKS = 200
NW_LAGS = 2
MAX_ITER = 40

BiasReference = Literal["run_mean", "long_run"]
"""What a bias sigma describes: ``"run_mean"``, the error of the estimate against the mean
over the run of a wandering bias; ``"long_run"``, against the unit's long-run (ensemble) bias,
which a certificate carries. The two differ by the wander's own average over the run, whose
variance ≈ 2τ_w²T_c/T for a Gauss–Markov wander of level τ_w and correlation time T_c over a
run of T ≫ T_c (Papoulis, variance of a time average)."""


@dataclass(frozen=True)
class DynamicFit:
    """Result of :func:`fit_dynamic_batch`.

    :param names: parameter names (``spec.names``).
    :param theta: (p,) estimate.
    :param cov: (p, p) sandwich covariance (module docstring).
    :param cov_white: (p, p) (Jᵀ W J)⁻¹, the covariance if the residuals were white.
    :param noise_sigma: (3,) residual standard deviation per channel (channel units).
    :param residual_rms: RMS of all residuals (channel units).
    :param n_used: samples used; :param n_blocks: score blocks of the sandwich.
    :param iterations: Gauss-Newton iterations; :param converged: the step became negligible.
    :param bias_reference: what the bias sigma describes (:data:`BiasReference`): the
        sandwich over blocks of the run measures the scatter of the bias about the run's
        mean, not the wander's own average over the run (docs/noise-model.md).
    """

    spec: ModelSpec
    names: tuple[str, ...]
    theta: FloatArray
    cov: FloatArray
    cov_white: FloatArray
    noise_sigma: FloatArray
    residual_rms: float
    n_used: int
    n_blocks: int
    iterations: int
    converged: bool
    bias_reference: BiasReference = "run_mean"
    wander: BlockWander | None = None
    cov_run_mean: FloatArray | None = None

    @property
    def bias_sigma_run_mean(self) -> FloatArray:
        """(3,) the bias sigma against the run's mean bias (channel units): the white bound and
        the wander's share that is not its own average over the run (``dynamic_wander``), each
        at least the sandwich's; equal to the bias sigma when no wander was estimated."""
        cov = self.cov if self.cov_run_mean is None else self.cov_run_mean
        return np.asarray(np.sqrt(np.diag(cov)[:3]), dtype=float)

    @property
    def sigma(self) -> FloatArray:
        """(p,) one-sigma uncertainties from :attr:`cov`."""
        return np.sqrt(np.diag(self.cov))

    @property
    def inflation(self) -> FloatArray:
        """(p,) sigma over the white-noise sigma: how much the residuals' correlation costs."""
        return np.sqrt(np.diag(self.cov) / np.diag(self.cov_white))


def white_sigma(y: FloatArray) -> FloatArray:
    """(3,) robust white-noise standard deviation per channel: 1.4826·MAD(Δ²y)/√6."""
    d2 = np.diff(y, n=2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return np.asarray(1.4826 * mad / np.sqrt(6.0), dtype=float)


def linear_start(
    m: MotionData, y: FloatArray, g_m_s2: float, lever_arm_m: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Bias and K by linear least squares with f from the believed geometry (level, no skew).

    :returns: bias (3,), K (3, 3).
    :raises ValueError: the specific force does not span three dimensions.
    """
    spec = ModelSpec(())
    f = specific_force(initial_theta(spec, np.zeros(3), np.eye(3), lever_arm_m), m, spec, g_m_s2, lever_arm_m)
    X = np.column_stack([np.ones(f.shape[0]), f])[m.valid]
    sv = np.linalg.svd(X / np.maximum(np.abs(X).max(axis=0), 1e-300), compute_uv=False)
    if sv[-1] < 1e-6 * sv[0]:
        raise ValueError(
            "the table motion does not turn gravity through three dimensions: bias and K cannot be determined"
        )
    coef, *_ = np.linalg.lstsq(X, y[m.valid], rcond=None)
    return np.asarray(coef[0], dtype=float), np.asarray(coef[1:].T, dtype=float)


def _pass(
    theta: FloatArray,
    m: MotionData,
    y: FloatArray,
    w: FloatArray,
    spec: ModelSpec,
    g: float,
    lever: FloatArray,
    blocks: npt.NDArray[np.int64] | None,
    n_blocks: int,
    sums: tuple[FloatArray, FloatArray, FloatArray, npt.NDArray[np.int64]] | None = None,
) -> tuple[float, FloatArray, FloatArray, FloatArray | None, FloatArray]:
    """One pass over the data: cost, H, gradient Jᵀ W e, block scores, residual sum of squares per channel.

    ``sums`` (with blocks): arrays (n_w, 3, p), (n_w, 3), (n_w,) that receive Σ J, Σ e and
    the sample count per wander block, and each sample's wander block (n,).
    """
    p = spec.n_params
    H, grad, ss = np.zeros((p, p)), np.zeros(p), np.zeros(3)
    scores = np.zeros((n_blocks, p)) if blocks is not None else None
    cost = 0.0
    idx = np.flatnonzero(m.valid)
    for a in range(0, idx.shape[0], CHUNK_SAMPLES):
        sel = idx[a : a + CHUNK_SAMPLES]
        mc = m.take(sel, rates=spec.needs_rates)
        raw, J = predict(theta, mc, spec, g, lever, jacobian=True)
        assert J is not None
        e = y[sel] - raw
        ew = e * w
        cost += float(np.sum(e * ew))
        ss += np.sum(e * e, axis=0)
        Jw = J * np.sqrt(w)[None, :, None]
        Jf = Jw.reshape(-1, p)
        H += Jf.T @ Jf
        s = np.einsum("ncp,nc->np", J, ew)
        grad += s.sum(axis=0)
        if scores is not None and blocks is not None:
            np.add.at(scores, blocks[sel], s)
            if sums is not None:
                fine = sums[3][sel]
                np.add.at(sums[0], fine, J)
                np.add.at(sums[1], fine, e)
                np.add.at(sums[2], fine, 1.0)
    return cost, H, grad, scores, ss


def _solve(H: FloatArray, rhs: FloatArray, lam: float) -> FloatArray:
    d = np.sqrt(np.diag(H))
    d = np.where(d > 0, d, 1.0)
    Hs = H / np.outer(d, d) + lam * np.eye(H.shape[0])
    return np.asarray(np.linalg.solve(Hs, rhs / d) / d, dtype=float)


def newey_west(scores: FloatArray, lags: int = NW_LAGS) -> FloatArray:
    """Long-run covariance Σ_b s_b s_bᵀ + Bartlett-weighted lagged cross products, (p, p)."""
    S = scores.T @ scores
    for k in range(1, lags + 1):
        G = scores[:-k].T @ scores[k:]
        S += (1.0 - k / (lags + 1.0)) * (G + G.T)
    return np.asarray(S, dtype=float)


def fit_dynamic_batch(
    m: MotionData,
    y: npt.ArrayLike,
    g_m_s2: float,
    lever_arm_m: npt.ArrayLike,
    spec: ModelSpec,
    *,
    theta0: FloatArray | None = None,
    block_s: float | None = None,
    max_iter: int = MAX_ITER,
) -> DynamicFit:
    """Fit θ to raw samples y (n, 3) of the motion ``m``.

    :param g_m_s2: local gravity (m/s²).
    :param lever_arm_m: (3,) the believed lever arm (start value, and the value used
        when the model does not fit it) (m).
    :param theta0: start; default :func:`linear_start` and the believed geometry.
    :raises ValueError: non-finite samples, too few samples, or parameters the motion
        cannot determine (named, with the reason).
    """
    Y = np.asarray(y, dtype=float)
    lever = np.asarray(lever_arm_m, dtype=float).reshape(3)
    if Y.shape != (m.n, 3) or not np.all(np.isfinite(Y)):
        raise ValueError(f"raw samples must be finite with shape ({m.n}, 3), got {Y.shape}")
    p = spec.n_params
    n_used = int(m.valid.sum())
    if n_used < 3 * p:
        raise ValueError(f"{n_used} usable samples for {p} parameters")
    if theta0 is None:
        b0, K0 = linear_start(m, Y, g_m_s2, lever)
        theta0 = initial_theta(spec, b0, K0, lever)
    theta = np.array(theta0, dtype=float)
    sig = np.maximum(white_sigma(Y[m.valid]), 1e-12 * np.abs(Y).max())
    w = 1.0 / sig**2
    span_s = float(m.t_s[-1] - m.t_s[0])
    block = max(BLOCK_S, span_s / TARGET_BLOCKS) if block_s is None else float(block_s)
    blk = np.floor((m.t_s - m.t_s[0]) / block).astype(np.int64)
    n_blocks = int(blk[-1]) + 1
    lam, it, converged, reweighted = 1e-3, 0, False, False
    cost, H, grad, _, ss = _pass(theta, m, Y, w, spec, g_m_s2, lever, None, 0)
    check_information(H, spec.names)
    while it < max_iter:
        it += 1
        step = _solve(H, grad, lam)
        trial = theta + step
        c_new, H_new, g_new, _, ss_new = _pass(trial, m, Y, w, spec, g_m_s2, lever, None, 0)
        if c_new <= cost:
            decrease = cost - c_new
            theta, cost, H, grad, ss = trial, c_new, H_new, g_new, ss_new
            lam = max(lam / 10.0, 1e-9)
            if decrease < 1e-8 * max(cost, 1.0) or float(step @ H @ step) < 1e-8:
                if reweighted:
                    converged = True
                    break
                sig = np.sqrt(ss / n_used)
                w = 1.0 / sig**2
                reweighted = True
                cost, H, grad, _, ss = _pass(theta, m, Y, w, spec, g_m_s2, lever, None, 0)
        else:
            lam *= 10.0
            if lam > 1e8:
                break
    fine_s = max(BLOCK_S, span_s / WANDER_BLOCKS)
    fine = np.floor((m.t_s - m.t_s[0]) / fine_s).astype(np.int64)
    n_fine = int(fine[-1]) + 1
    sums = (np.zeros((n_fine, 3, p)), np.zeros((n_fine, 3)), np.zeros(n_fine), fine)
    cost, H, grad, scores, ss = _pass(theta, m, Y, w, spec, g_m_s2, lever, blk, n_blocks, sums)
    check_information(H, spec.names)
    assert scores is not None
    scores = scores[np.any(scores != 0, axis=1)]
    nb = scores.shape[0]
    Hinv = np.linalg.inv(H)
    cov_white = 0.5 * (Hinv + Hinv.T)
    used = sums[2] > 0
    mid_s = np.asarray(m.t_s[0] + (np.flatnonzero(used) + 0.5) * fine_s, dtype=float)
    wander = fit_block_wander(
        sums[0][used],
        sums[1][used],
        sums[2][used],
        mid_s,
        np.sqrt(1.0 / w),
        cov_white,
        channel_gain=np.linalg.norm(theta[3:12].reshape(3, 3), axis=1),
    )
    model = cov_white if wander is None else cov_white + wander.cov
    small = nb / (nb - p) if nb > p + 1 else np.inf
    sandwich = np.diag(Hinv @ newey_west(scores) @ Hinv) * small
    c = np.sqrt(np.maximum(sandwich / np.diag(model), 1.0))
    cov = model * np.outer(c, c)
    cov_run = None
    if wander is not None:
        model_run = cov_white + wander.cov_run_mean
        c_run = np.sqrt(np.maximum(sandwich / np.diag(model_run), 1.0))
        cov_run = model_run * np.outer(c_run, c_run)
    return DynamicFit(
        spec=spec,
        names=tuple(spec.names),
        theta=theta,
        cov=cov,
        cov_white=cov_white,
        noise_sigma=np.sqrt(ss / n_used),
        residual_rms=float(np.sqrt(ss.sum() / (3 * n_used))),
        n_used=n_used,
        n_blocks=nb,
        iterations=it,
        converged=converged,
        bias_reference="long_run" if wander is not None and wander.correlated else "run_mean",
        wander=wander,
        cov_run_mean=cov_run,
    )
