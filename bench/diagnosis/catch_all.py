"""What a catch-all (the per-window pose error) must show before it is claimed.

The pose error gives every window two free angles, held together only by one variance
σ_p²: it can absorb almost any pattern of window means. It is therefore

1. charged its effective degrees of freedom, not one parameter. For the GLS fit with
   covariance C = C₀ + σ_p² G (G = blockdiag_w J_w J_wᵀ) the predicted pose offsets are
   J p̂ = σ_p² G P z with P = C⁻¹ − C⁻¹ X (Xᵀ C⁻¹ X)⁻¹ Xᵀ C⁻¹, a linear smoother of z,
   whose trace is the effective number of parameters (Hastie & Tibshirani, Generalized
   Additive Models (1990) §3.5; Hodges & Sargent, Biometrika 88 (2001) 367):

       edf = tr(σ_p² G P),

   and its BIC change is the conditional one (Vaida & Blanchard, Biometrika 92 (2005) 351):
   the likelihood of the data given the predicted angles, r_c = z − X θ̂ − J p̂ under C₀,
   against the model without it, plus edf · ln n (the marginal likelihood with one
   parameter would let 2m angles in for the price of one);

2. asked for the evidence its physics implies: a pose error turns gravity, so it moves
   the window means on the channels perpendicular to gravity together, by the same angle
   variance on each. With r the residuals of the model without the pose error (GLS under
   C₀) and D_i the diagonal that picks channel i weighted by 1/C₀, q_i = rᵀ D_i r has,
   under the pose model, E[q_i] = tr(D_i M) and Var[q_i] = 2 tr(D_i M D_i M), M = R C Rᵀ,
   R = I − X (Xᵀ C₀⁻¹ X)⁻¹ Xᵀ C₀⁻¹. Judged as a scaled χ² of the same mean and variance
   (Satterthwaite), a channel whose q_i lies below the lower ``Thresholds.physics_alpha`` quantile
   shows far less than the angles must move it: the pose error is then not the physics,
   whatever its likelihood.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.likelihood import NoiseParams, covariance, without_pose
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.window_covariance import WindowCovariance

CHANNELS = ("ax", "ay", "az")


@dataclass(frozen=True)
class PoseCheck:
    """The catch-all's accounts.

    :param edf: effective degrees of freedom of the pose offsets.
    :param expected: (3,) E[q_i] under the pose model; :param observed: (3,) q_i.
    :param p_low: (3,) lower-tail probability of each observed q_i under the pose model.
    :param alpha: the level below which a channel does not show it (``Thresholds.physics_alpha``).
    """

    edf: float
    loglik_conditional: float
    expected: FloatArray
    observed: FloatArray
    p_low: FloatArray
    alpha: float

    @property
    def consistent(self) -> bool:
        """Every channel shows at least what the pose error implies (at ``alpha``)."""
        return bool(np.all(self.p_low >= self.alpha))

    def text(self) -> str:
        """Why a pose error was not claimed (for ``notes``)."""
        bad = [i for i in range(3) if self.p_low[i] < self.alpha]
        parts = ", ".join(
            f"{CHANNELS[i]} shows chi2 {self.observed[i]:.1f} where the pose error implies "
            f"{self.expected[i]:.1f} (p = {self.p_low[i]:.1e})"
            for i in bad
        )
        return (
            "a random pose error would absorb the mismatch, but a pose error turns gravity and moves "
            f"the channels perpendicular to it together: {parts}; not claimed"
        )


def channel_forms(
    C_true: FloatArray, C_fit: FloatArray, X: FloatArray, z: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per channel i: q_i = rᵀ D_i r for the GLS residual r = R z under ``C_fit``, D_i the
    diagonal of channel i weighted by 1/diag(C_fit), with its mean and variance when z has
    covariance ``C_true``: E = tr(D_i M), Var = 2 tr(D_i M D_i M), M = R C_true Rᵀ.

    :returns: (observed q (3,), expected (3,), variance (3,)).
    """
    n = z.shape[0]
    f = cho_factor(C_fit, lower=True)
    CiX = cho_solve(f, X)
    R = np.eye(n) - X @ np.linalg.solve(X.T @ CiX, CiX.T)
    r = R @ z
    M = R @ C_true @ R.T
    d = 1.0 / np.diag(C_fit)
    q, e, v = np.zeros(3), np.zeros(3), np.zeros(3)
    for i in range(3):
        Di = np.zeros(n)
        Di[i::3] = d[i::3]
        DM = Di[:, None] * M
        q[i] = float(np.sum(Di * r * r))
        e[i] = float(np.trace(DM))
        v[i] = 2.0 * float(np.sum(DM * DM.T))
    return q, e, v


def exponential_kernel_product(t_s: FloatArray, corr_time_s: float, Y: FloatArray) -> FloatArray:
    """P Y for P_ww' = exp(−|t_w − t_w'| / T) (T = ``corr_time_s``; T ≤ 0: P = I), in O(m p).

    In time order, with ρ_k = exp(−(t_k − t_{k−1}) / T), the lower part of P Y is the forward
    recursion f_k = Y_k + ρ_k f_{k−1} and the upper part the backward g_k = Y_k + ρ_{k+1} g_{k+1};
    P Y = f + g − Y (Rybicki & Press, ApJ 398 (1992) 169: the exponential kernel is Markov).

    :param t_s: (m,) times (s), any order; :param Y: (m,) or (m, p).
    :returns: P Y, the shape of Y.
    """
    if corr_time_s <= 0:
        return np.array(Y, dtype=float, copy=True)
    order = np.argsort(t_s, kind="stable")
    Ys = np.asarray(Y, dtype=float)[order]
    rho = np.exp(-np.diff(np.asarray(t_s, dtype=float)[order]) / corr_time_s)
    f = Ys.copy()
    g = Ys.copy()
    for k in range(1, Ys.shape[0]):
        f[k] += rho[k - 1] * f[k - 1]
    for k in range(Ys.shape[0] - 2, -1, -1):
        g[k] += rho[k] * g[k + 1]
    out = np.empty_like(Ys)
    out[order] = f + g - Ys
    return out


def gls_channel_forms(
    cov: WindowCovariance, X: FloatArray, z: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`channel_forms` for a model fitted under its own covariance (``C_true = C_fit = C``),
    in O(m) time and memory: nothing m × m is formed.

    The residual comes from the O(m) factor of ``cov``. Within channel i the covariance is
    C_i = diag(b) + τ_i² P (b_w = B_w,ii, P the wander's exponential kernel) and the residual
    covariance M_i = C_i − H_i, H_i = X_i A⁻¹ X_iᵀ, A = XᵀC⁻¹X (GLS). With D = diag(1/diag C_i),
    G = X_iᵀ D X_i and W = (D X_i)ᵀ C_i (D X_i):

        E[q_i] = tr(D M_i) = Σ_w d_w C_i,ww − tr(A⁻¹ G),
        Var[q_i] / 2 = tr(D M_i D M_i) = tr(D C_i D C_i) − 2 tr(A⁻¹ W) + tr(A⁻¹ G A⁻¹ G),
        tr(D C_i D C_i) = Σ_w d_w² (b_w² + 2 τ_i² b_w) + τ_i⁴ dᵀ P⁽²⁾ d,

    P⁽²⁾ = P ∘ P the kernel at half the correlation time; every product with P or P⁽²⁾ by
    :func:`exponential_kernel_product`.

    :param cov: C in its O(m) form; :param X: (3m, p) design; :param z: (3m,) window means.
    :returns: (observed q (3,), expected (3,), variance (3,)) as :func:`channel_forms`.
    """
    fac = cov.factor()
    CiX = fac.solve(X)
    A = X.T @ CiX
    r = z - X @ np.linalg.solve(A, CiX.T @ z)
    A_inv = np.linalg.inv(A)
    d = 1.0 / cov.diagonal()
    T = cov.corr_time_s
    q, e, v = np.zeros(3), np.zeros(3), np.zeros(3)
    for i in range(3):
        Xi = X[i::3]
        di = d[i::3]
        b = cov.blocks[:, i, i]
        tau2 = max(float(cov.tau2[i]), 0.0)
        Y = di[:, None] * Xi
        CY = b[:, None] * Y + (tau2 * exponential_kernel_product(cov.mid_s, T, Y) if tau2 > 0 else 0.0)
        G = Xi.T @ Y
        AG = A_inv @ G
        W = Y.T @ CY
        dCdC = float(np.sum(di * di * (b * b + 2.0 * tau2 * b)))
        if tau2 > 0:
            dCdC += tau2 * tau2 * float(di @ exponential_kernel_product(cov.mid_s, T / 2.0, di))
        q[i] = float(np.sum(di * r[i::3] ** 2))
        e[i] = float(np.sum(di * (b + tau2))) - float(np.trace(AG))
        v[i] = 2.0 * (dCdC - 2.0 * float(np.sum(A_inv * W.T)) + float(np.sum(AG * AG.T)))
    return q, e, v


def satterthwaite_tails(q: FloatArray, e: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(lower, upper) tail probabilities of q judged as c·χ²_ν with mean e and variance v."""
    lo, up = np.ones_like(q), np.ones_like(q)
    for i in range(q.size):
        if e[i] > 0 and v[i] > 0:
            c, nu = v[i] / (2.0 * e[i]), 2.0 * e[i] ** 2 / v[i]
            lo[i] = float(chi2_dist.cdf(q[i] / c, nu))
            up[i] = float(chi2_dist.sf(q[i] / c, nu))
    return lo, up


def pose_check(
    V: FloatArray,
    mid_s: FloatArray,
    noise: NoiseParams,
    J: FloatArray,
    X: FloatArray,
    z: FloatArray,
    fixed: FloatArray | None = None,
    th: Thresholds = THRESHOLDS,
) -> PoseCheck:
    """Effective dof and per-channel evidence of a fitted pose error (module docstring).

    :param noise: the noise fitted with the pose error (``pose_var_rad2 > 0``).
    :param J: (m, 3, 2) pose response; :param X: (3m, p) design; :param z: (3m,) observations.
    """
    m = V.shape[0]
    n = 3 * m
    C1 = covariance(V, mid_s, noise, J, fixed)
    C0 = covariance(V, mid_s, without_pose(noise), J, fixed)
    G = np.zeros((n, n))
    for w in range(m):
        G[3 * w : 3 * w + 3, 3 * w : 3 * w + 3] = J[w] @ J[w].T
    f1 = cho_factor(C1, lower=True)
    C1iX = cho_solve(f1, X)
    P = cho_solve(f1, np.eye(n)) - C1iX @ np.linalg.solve(X.T @ C1iX, C1iX.T)
    edf = float(noise.pose_var_rad2 * np.trace(G @ P))
    r_c = z - X @ np.linalg.solve(X.T @ C1iX, C1iX.T @ z) - noise.pose_var_rad2 * G @ (P @ z)
    f0 = cho_factor(C0, lower=True)
    logdet0 = 2.0 * float(np.sum(np.log(np.diag(f0[0]))))
    ll_c = -0.5 * (float(r_c @ cho_solve(f0, r_c)) + logdet0 + n * np.log(2.0 * np.pi))
    q, e, v = channel_forms(C1, C0, X, z)
    p_low, _ = satterthwaite_tails(q, e, v)
    return PoseCheck(
        edf=edf, loglik_conditional=ll_c, expected=e, observed=q, p_low=p_low, alpha=th.physics_alpha
    )
