"""Unbiased (MINQUE) estimate of the between-window variance components at a static fit's weights.

The static fit (``bench.estimation.static_fit``) weights its windows with S_w = V_w + E_w, the
excess E_w a Paule-Mandel estimate clipped at zero and inflated by ν/(ν − 2). As a variance of
the fit's estimator that excess is biased up where the windows agree within their own noise
(E[max(0, τ̂²)] > 0 when τ² = 0, then multiplied again): a budget built on it stated u_c
1.05–1.25× the spread of the misalignments with no excess at all (docs/noise-model.md).

Here the excess enters the Type A variance only in the amount the residuals support. With the
windows stacked (3m,), y = H θ + e, Cov(e) = V + Σ_l φ_l G_l, the components

    G_pose = blockdiag(K (I − f̂_w f̂_wᵀ) Kᵀ)   (pose error, ``window_noise.pose_scatter``),
    G_i    = blockdiag(e_i e_iᵀ), i = x, y, z  (each channel's own excess),

and R = W − W H (Hᵀ W H)⁻¹ Hᵀ W with W = P⁻¹ the weights of a prior P, φ of the active
components solves the MINQUE equations (C. R. Rao, J. Multivariate Anal. 1 (1971) 257; one step
of REML from the prior P, Harville, JASA 72 (1977) 320; for one component and a mean, the moment
estimator of DerSimonian & Laird, Control. Clin. Trials 7 (1986) 177, without its truncation):

    Σ_l tr(R G_k R G_l) φ_l = yᵀ R G_k R y − tr(R G_k R V) − Σ_X d_Xᵀ R G_k R d_X,

d_X the move u(X) (∂y/∂X − K ∂f/∂X) of each Type B input (``type_a.residual_moves``), whose
expected share is thus taken out. E[yᵀ R G_k R y] = tr(R G_k R Cov(y)) for fixed W (R H = 0),
so φ̂ is unbiased for any fixed prior; it is not clipped at zero (a negative φ̂ is the
sampling scatter of a small excess; clipping it is what biased the old estimate). The first
prior is the fit's S; each of :data:`PRIOR_STEPS` further steps takes P = V + the positive part
of each window's Σ φ̂_l G_l of the step before (iterated MINQUE, whose fixed point solves the
REML equations: Rao & Kleffe, Estimation of Variance Components and Applications, 1988, ch. 9).
The fit's Paule-Mandel S
spreads a pose scatter over every direction of a window, so with S as the prior the readings
along gravity, the only ones that tell a channel's own excess from pose scatter, were weighted as
noisy as the tilts: with pose errors 50× the window noise (3′ on 198 s windows) the own
components came out with standard deviations 100-200× the window variance, and u_j² swung from
the floor to 50× a_j within one run (docs/noise-model.md). Only φ̂ uses these weights; the
estimator θ̂ = A y below is the fit's. Three models are estimated (pose alone, own alone,
both: :data:`MODELS`) and the one with the largest restricted log-likelihood less
its number of components is used. The variance of the fit's estimator θ̂ = A y,
A = (Hᵀ S⁻¹ H)⁻¹ Hᵀ S⁻¹ (the fit's weights), is then

    C_A = A (V + Σ_l φ̂_l G_l) Aᵀ,   u_j² = a_j + Σ_l c_jl φ̂_l,   a_j = (A V Aᵀ)_jj, c_jl = (A G_l Aᵀ)_jj,

with degrees of freedom (Satterthwaite, GUM G.4)

    ν_j = 2 u_j⁴ / Var(u_j²),   Var(u_j²) = c_jᵀ Cov(φ̂) c_j,   Cov(φ̂) = F⁻¹ Ω F⁻¹,

F_kl = tr(R G_k R G_l), Ω_kl = 2 tr(R G_k R Ŝ R G_l R Ŝ) (Gaussian quadratic forms), Ŝ = V +
Σ_l φ̂_l G_l with each window's negative eigenvalues set to zero (with the clipped φ̂ instead,
Ŝ overstated the spread of u_j² about 2× over 200 simulated sessions). V is taken as known
(batch means pooled over the run: many degrees of freedom). Where u_j² falls below
:data:`FLOOR` a_j (a large negative draw of φ̂) it is held at that floor; ν_j then stays that
of the unclipped estimate, never below :data:`MIN_DOF`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.static_design import design_rows
from bench.estimation.window_noise import pose_scatter

FloatArray = npt.NDArray[np.float64]

FLOOR = 0.5
"""Lowest u_j² as a fraction of the within-window part a_j: reached only when φ̂ is far below
zero (a draw the study counts; it keeps a stated variance positive)."""
MODELS = ((0,), (1, 2, 3), (0, 1, 2, 3))
MODEL_NAMES = ("pose scatter", "each channel's own excess", "pose scatter and each channel's own excess")
"""The excess models compared: pose scatter alone, each channel's own excess alone, both. The
one with the largest restricted log-likelihood less its number of components (Akaike, IEEE
Trans. Autom. Control 19 (1974) 716) is used. With both always estimated, where pose errors
dominate the own excess could not be told from them (its standard deviation 4× the window
noise over 80 simulated runs) and carried that noise into every bias and diagonal K (ν ≈ 1,
k = 14); with the pose scatter alone tested first an own excess was read as pose scatter."""
PRIOR_STEPS = 10
"""MINQUE steps after the first, each with the prior of the step before's φ̂ (its negative part
dropped), towards REML (module docstring)."""
MIN_DOF = 1.0
"""Lowest ν_j stated: below one degree of freedom t_p(ν) is not defined (GUM G.6.4 rounds down)."""
COMPONENTS = ("pose scatter", "own excess, channel x", "own excess, channel y", "own excess, channel z")


@dataclass(frozen=True)
class ExcessMoments:
    """The unbiased Type A covariance of a static fit's estimator and its degrees of freedom.

    :param cov: (12, 12) C_A = A (V + Σ φ̂_l G_l) Aᵀ (diagonal floored, module docstring).
    :param dof: (12,) ν_j of each diagonal element (Satterthwaite).
    :param components: (4,) φ̂: pose variance t ((m/s²)²), own excess τ_x², τ_y², τ_z²
        (channel units²), unclipped.
    :param components_sd: (4,) standard deviations of φ̂.
    :param floored: (12,) the parameters whose u_j² was held at the floor.
    :param model: the excess model chosen (:data:`MODEL_NAMES`).
    """

    cov: FloatArray
    dof: FloatArray
    components: FloatArray
    components_sd: FloatArray
    floored: npt.NDArray[np.bool_]
    model: str = ""


def _minque(
    R: FloatArray,
    y: FloatArray,
    Vb: FloatArray,
    V: FloatArray,
    G: list[FloatArray],
    blocks: list[FloatArray],
    D: FloatArray,
    active: tuple[int, ...],
) -> tuple[FloatArray, FloatArray]:
    """φ̂ (4,) and Cov(φ̂) (4, 4) of the components ``active`` (the others zero), module docstring.

    :param R: (3m, 3m) the fit's residual operator; :param y: (3m,) the stacked means;
    :param Vb: (3m, 3m) and :param V: (m, 3, 3) the within-window covariances;
    :param G: the components' (3m, 3m) shapes, :param blocks: the same as (m, 3, 3) blocks;
    :param D: (n, 3m) the Type B inputs' moves u(X) d_X.
    """
    Ga = [G[i] for i in active]
    RG = [R @ g for g in Ga]
    F = np.array([[np.trace(a @ b) for b in RG] for a in RG])
    ry = R @ y
    RD = D @ R  # rows: (R d_X)ᵀ, R symmetric
    RV = R @ Vb
    q = np.array(
        [ry @ g @ ry - np.trace(rg @ RV) - float(np.sum((RD @ g) * RD)) for g, rg in zip(Ga, RG, strict=True)]
    )
    Finv = np.linalg.pinv(F)
    phi_a = Finv @ q
    lam, vec = np.linalg.eigh(V + sum(p * blocks[i] for p, i in zip(phi_a, active, strict=True)))
    S_hat = _block_diag(np.einsum("wab,wb,wcb->wac", vec, np.clip(lam, 0.0, None), vec))
    RS = R @ S_hat
    B = [rg @ RS for rg in RG]  # R G_k R Ŝ
    omega = np.array([[2.0 * np.trace(a @ b) for b in B] for a in B])
    phi, cov_phi = np.zeros(4), np.zeros((4, 4))
    idx = np.array(active)
    phi[idx] = phi_a
    cov_phi[np.ix_(idx, idx)] = Finv @ omega @ Finv
    return phi, cov_phi


def _iterated(
    H: FloatArray,
    R: FloatArray,
    y: FloatArray,
    Vb: FloatArray,
    V: FloatArray,
    G: list[FloatArray],
    blocks: list[FloatArray],
    D: FloatArray,
    active: tuple[int, ...],
) -> tuple[FloatArray, FloatArray]:
    """φ̂ and Cov(φ̂) of :func:`_minque`, its prior iterated :data:`PRIOR_STEPS` times (module
    docstring): each step weights with V + the positive part of each window's Σ φ̂_l G_l."""
    phi, cov_phi = _minque(R, y, Vb, V, G, blocks, D, active)
    for _ in range(PRIOR_STEPS):
        lam, vec = np.linalg.eigh(sum(phi[i] * blocks[i] for i in active))
        excess = np.einsum("wab,wb,wcb->wac", vec, np.clip(lam, 0.0, None), vec)
        W = _block_diag(np.linalg.inv(V + excess))
        HtW = H.T @ W
        R_step = W - HtW.T @ np.linalg.solve(HtW @ H, HtW)
        phi, cov_phi = _minque(0.5 * (R_step + R_step.T), y, Vb, V, G, blocks, D, active)
    return phi, cov_phi


def _reml_loglik(
    H: FloatArray, y: FloatArray, V: FloatArray, blocks: list[FloatArray], phi: FloatArray
) -> float:
    """Restricted log-likelihood (Patterson & Thompson 1971) of the stacked means y (3m,) with
    design H (3m, 12) under the window blocks V + Σ φ_l G_l (eigenvalues held at least a
    millionth of tr V_w)."""
    lam, vec = np.linalg.eigh(V + sum(p * g for p, g in zip(phi, blocks, strict=True)))
    lam = np.maximum(lam, 1e-6 * np.trace(V, axis1=1, axis2=2)[:, None])
    Winv = np.einsum("wab,wb,wcb->wac", vec, 1.0 / lam, vec)
    W = _block_diag(Winv)
    HtW = H.T @ W
    N = HtW @ H
    theta = np.linalg.solve(N, HtW @ y)
    r = y - H @ theta
    return float(-0.5 * (np.sum(np.log(lam)) + np.linalg.slogdet(N)[1] + r @ W @ r))


def _block_diag(blocks: FloatArray) -> FloatArray:
    """(3m, 3m) block-diagonal matrix of (m, 3, 3) blocks."""
    m = blocks.shape[0]
    out = np.zeros((3 * m, 3 * m))
    for w in range(m):
        out[3 * w : 3 * w + 3, 3 * w : 3 * w + 3] = blocks[w]
    return out


def excess_moments(
    f_m_s2: FloatArray,
    y_mean: FloatArray,
    y_cov: FloatArray,
    K: FloatArray,
    weights_cov: FloatArray,
    known: FloatArray | None = None,
) -> ExcessMoments:
    """The Type A covariance of the fit with weights ``weights_cov`` (module docstring).

    :param f_m_s2: (m, 3) specific force of the windows (m/s²), m > 4.
    :param y_mean: (m, 3) window means (channel units).
    :param y_cov: (m, 3, 3) their within-window covariances V_w.
    :param K: (3, 3) the fitted scale matrix (shape of the pose component).
    :param weights_cov: (m, 3, 3) S_w, the covariances the fit weighted with.
    :param known: (n, m, 3) u(X) d_X of the Type B inputs (channel units), or ``None``.
    :returns: :class:`ExcessMoments`; with m ≤ 4 windows (no residual degrees of freedom) the
        within-window part A V Aᵀ alone, ν = ∞.
    :raises ValueError: shapes disagree.
    """
    f, y = np.asarray(f_m_s2, dtype=float), np.asarray(y_mean, dtype=float)
    V, S = np.asarray(y_cov, dtype=float), np.asarray(weights_cov, dtype=float)
    m = f.shape[0]
    if f.shape != (m, 3) or y.shape != (m, 3) or V.shape != (m, 3, 3) or S.shape != (m, 3, 3):
        raise ValueError(
            f"expected f (m, 3), means (m, 3), covariances (m, 3, 3) twice; "
            f"got {f.shape}, {y.shape}, {V.shape}, {S.shape}"
        )
    kn = np.zeros((0, m, 3)) if known is None else np.asarray(known, dtype=float)
    H = design_rows(f).reshape(3 * m, 12)
    W = _block_diag(np.linalg.inv(S))
    HtW = H.T @ W
    Ninv = np.linalg.inv(HtW @ H)
    A = Ninv @ HtW
    R = W - HtW.T @ A
    eye = np.eye(3)
    blocks = [pose_scatter(K, f)] + [np.tile(np.outer(e, e), (m, 1, 1)) for e in eye]
    G = [_block_diag(g) for g in blocks]
    if m <= 4:  # no residual degrees of freedom: nothing to estimate the excess from
        C = A @ _block_diag(V) @ A.T
        return ExcessMoments(
            0.5 * (C + C.T), np.full(12, np.inf), np.zeros(4), np.zeros(4), np.zeros(12, bool), "none"
        )
    Vb = _block_diag(V)
    D = kn.reshape(kn.shape[0], 3 * m)
    fits = [_iterated(H, R, y.reshape(-1), Vb, V, G, blocks, D, active) for active in MODELS]
    aic = np.array(
        [
            _reml_loglik(H, y.reshape(-1), V, blocks, phi) - len(act)
            for (phi, _), act in zip(fits, MODELS, strict=True)
        ]
    )
    best = int(np.argmax(aic))
    phi, cov_phi = fits[best]
    a = np.einsum("ja,ab,jb->j", A, Vb, A)
    c = np.array([np.einsum("ja,ab,jb->j", A, g, A) for g in G]).T  # (12, 4)
    u2 = a + c @ phi
    floored = u2 < FLOOR * a
    var_u2 = np.einsum("jk,kl,jl->j", c, cov_phi, c)
    u2_used = np.where(floored, FLOOR * a, u2)
    with np.errstate(divide="ignore"):
        dof = np.where(var_u2 > 0, 2.0 * u2_used**2 / np.maximum(var_u2, 1e-300), np.inf)
    dof = np.maximum(dof, MIN_DOF)
    cov = A @ (Vb + sum(p * g for p, g in zip(phi, G, strict=True))) @ A.T
    cov = 0.5 * (cov + cov.T)
    idx = np.arange(12)
    cov[idx, idx] = u2_used
    return ExcessMoments(
        cov=cov,
        dof=dof,
        components=phi,
        components_sd=np.sqrt(np.clip(np.diag(cov_phi), 0.0, None)),
        model=MODEL_NAMES[best],
        floored=floored,
    )
