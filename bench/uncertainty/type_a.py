"""The Type A part of a static budget: the excess between windows in the amount the data support,
with the Type B inputs' share taken out.

The static fit (``bench.estimation.static_fit``) weights its windows with V_w + E_w, E_w a
between-window excess (a pose variance t common to the channels and each channel's own τ_i²,
Paule-Mandel) clipped at zero and inflated by ν/(ν − 2). As the fit's variance that excess is
biased up where the windows agree within their own noise (E[max(0, τ̂²)] > 0 for τ² = 0): a
budget built on it stated u_c 1.05–1.3× the spread of the misalignments' errors with no excess
at all (docs/noise-model.md). A Type B input X of the budget (``bench.uncertainty.budget``)
moves every window mean by ξ_X d_X (ξ_X of standard uncertainty u(X), one draw for the run):

    d_X,w = ∂y_w/∂X − K ∂f_w/∂X          (m, 3), channel units per unit X;

the part the design [1, f_w] cannot absorb stays in the residuals and would be counted again
in the excess.

The Type A covariance is that of the fit's own estimator θ̂ = A y (its weights W_w = (V_w +
E_w)⁻¹, its values: no refit) with the excess estimated without bias at those weights and each
input's expected share taken out (MINQUE, ``excess_moments``; Rao 1971, the moment estimator
of DerSimonian & Laird 1986 for a variance component generalised to the fit's design):

    C_A = A (V + φ̂_pose G_pose + Σ_i φ̂_i G_i) Aᵀ,   A = (Σ H_wᵀ W_w H_w)⁻¹ Hᵀ W,

φ̂ not clipped at zero, so over runs E[C_A,jj] = Var(θ̂_j) whether or not the windows show an
excess; each diagonal element has its Satterthwaite degrees of freedom (:attr:`TypeA.dof`).
:meth:`TypeA.ratio` is √(C_A,jj / C_jj) with C = N⁻¹ the fit's own covariance recomputed from
the same design: the fit's stated σ_j times it is the Type A line. The fit's slow-wander model
(windows correlated in time) is not covered: its covariance is not a per-window excess
(``static_fit.fit_static`` with window times).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.static_design import PARAMETER_NAMES, design_rows
from bench.estimation.static_fit import between_window_excess
from bench.uncertainty.budget import TypeBInput, moves
from bench.uncertainty.excess_moments import COMPONENTS, excess_moments

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class TypeA:
    """The Type A part of a static fit with the excess in the amount the data support.

    :param cov: (12, 12) C_A, the fit's estimator under V + the unbiased excess (module docstring).
    :param cov_fit: (12, 12) the fit's covariance N⁻¹ recomputed from its design and excess.
    :param weights_cov: (m, 3, 3) V_w + E_w, the window covariances the fit weighted with.
    :param dof: (12,) Satterthwaite degrees of freedom of each C_A,jj.
    :param components: (4,) the excess φ̂ (``excess_moments.COMPONENTS``: pose variance t in
        (m/s²)², each channel's own τ² in channel units²), unclipped.
    :param components_sd: (4,) their standard deviations.
    :param model: the excess model used (``excess_moments.MODEL_NAMES``).
    :param below_zero: the components estimated below zero (no excess shown there).
    :param floored: names of the parameters whose variance was held at the floor
        (``excess_moments.FLOOR`` of the within-window part).
    """

    cov: FloatArray
    cov_fit: FloatArray
    weights_cov: FloatArray
    dof: FloatArray
    components: FloatArray
    components_sd: FloatArray
    model: str
    below_zero: tuple[str, ...]
    floored: tuple[str, ...]

    def ratio(self) -> FloatArray:
        """(12,) √(C_A,jj / C_jj): the factor on each of the fit's stated σ_j."""
        d, d0 = np.diag(self.cov), np.diag(self.cov_fit)
        return np.sqrt(np.where(d0 > 0, d / np.where(d0 > 0, d0, 1.0), 1.0))


def residual_moves(inputs: Sequence[TypeBInput], K: FloatArray, m: int) -> FloatArray:
    """(n, m, 3) u(X) d_X = u(X) (∂y_w/∂X − K ∂f_w/∂X) of each input, channel units."""
    Km = np.asarray(K, dtype=float).reshape(3, 3)
    out = np.zeros((len(inputs), m, 3))
    for n, inp in enumerate(inputs):
        df, dy = moves(inp, m)
        out[n] = inp.u * (dy - df @ Km.T)
    return out


def type_a_without_type_b(
    f_m_s2: FloatArray,
    y_mean: FloatArray,
    y_cov: FloatArray,
    K: FloatArray,
    inputs: Sequence[TypeBInput],
) -> TypeA:
    """The Type A part of the static fit of (f, y) with the inputs' share removed (module docstring).

    :param f_m_s2: (m, 3) specific force of the fit's windows (m/s²).
    :param y_mean: (m, 3) the window means the fit used (channel units).
    :param y_cov: (m, 3, 3) their within-window covariances (``window_noise``).
    :param K: (3, 3) the fitted scale matrix.
    :param inputs: the budget's Type B inputs.
    :raises ValueError: shapes or values wrong (``static_fit``, ``budget``).
    """
    f = np.asarray(f_m_s2, dtype=float)
    V = np.asarray(y_cov, dtype=float)
    V = 0.5 * (V + np.transpose(V, (0, 2, 1)))
    m = f.shape[0]
    E, _, _ = between_window_excess(f, y_mean, V, K)
    S = V + E
    H = design_rows(f)
    HtW = np.einsum("wai,wab->wib", H, np.linalg.inv(S))
    Ninv = np.linalg.inv(np.einsum("wib,wbj->ij", HtW, H))
    em = excess_moments(f, y_mean, V, K, S, residual_moves(inputs, K, m))
    return TypeA(
        cov=em.cov,
        cov_fit=0.5 * (Ninv + Ninv.T),
        weights_cov=S,
        dof=em.dof,
        components=em.components,
        components_sd=em.components_sd,
        model=em.model,
        below_zero=tuple(c for c, p in zip(COMPONENTS, em.components, strict=True) if p < 0),
        floored=tuple(n for n, x in zip(PARAMETER_NAMES, em.floored, strict=True) if x),
    )
