"""The Type A part of a static budget with the Type B inputs' share of the scatter taken out.

The static fit (``bench.estimation.static_fit``) estimates a between-window excess (a pose
variance t common to the channels and each channel's own τ_i², Paule-Mandel) from its
residuals. A Type B input X of the budget (``bench.uncertainty.budget``) moves every window
mean by ξ_X d_X (ξ_X of standard uncertainty u(X), one draw for the whole run):

    d_X,w = ∂y_w/∂X − K ∂f_w/∂X          (m, 3), channel units per unit X.

The part of d_X the design [1, f_w] cannot absorb, P⊥ d_X, stays in the residuals, so the
residual sum of squares Q of channel i has the expectation

    E[Q_i] = (m − 4) + Σ_X u(X)² ‖P⊥ d_X,i‖²_W,

and the plain estimate of the excess (Q_i = m − 4) takes the inputs' scatter into the Type A
line, where the budget then adds the same inputs again as Type B lines. Here each statistic
has the inputs' expected share taken out before it is equated to its degrees of freedom
(``window_noise.known_share``), the solution clipped at zero (an input stated larger than the
scatter the run shows leaves no excess; the within-window noise stays), so each input is
counted once.

The Type A covariance is that of the fit's own estimator θ̂ = N⁻¹ Σ Hᵀ W y (the weights W_w =
(V_w + E_w)⁻¹ with the excess E_w the fit estimated; its values are not refitted) under the
window covariances with the inputs' share removed, S'_w = V_w + E'_w (a sandwich):

    C_A = N⁻¹ (Σ_w H_wᵀ W_w S'_w W_w H_w) N⁻¹,   N = Σ_w H_wᵀ W_w H_w.

:meth:`TypeA.ratio` is √(C_A,jj / C_jj) with C = N⁻¹ the fit's own covariance recomputed from
the same design: the fit's stated σ_j times it is the Type A line (exactly σ_j when nothing is
taken out). The fit's slow-wander model (windows correlated in time) is not covered: its
covariance is not a per-window excess (``static_fit.fit_static`` with window times).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.static_design import design_rows
from bench.estimation.static_fit import between_window_excess
from bench.uncertainty.budget import TypeBInput, moves

FloatArray = npt.NDArray[np.float64]

CHANNELS = ("x", "y", "z")


@dataclass(frozen=True)
class TypeA:
    """The Type A part of a static fit with and without the Type B inputs' share.

    :param cov: (12, 12) C_A, the fit's estimator under the window covariances with the share removed.
    :param cov_fit: (12, 12) the fit's covariance N⁻¹ recomputed from its design and excess.
    :param weights_cov: (m, 3, 3) V_w + E_w, the window covariances the fit weighted with.
    :param pose_var: (fit, removed) pose variance t, (m/s²)², before the ν/(ν − 2) inflation.
    :param own_var: (2, 3) each channel's own excess τ² (fit, removed), channel units², before
        the inflation.
    :param clipped: the components that were positive in the fit and are zero with the share
        removed (e.g. ``"own excess, channel y"``).
    """

    cov: FloatArray
    cov_fit: FloatArray
    weights_cov: FloatArray
    pose_var: tuple[float, float]
    own_var: FloatArray
    clipped: tuple[str, ...]

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
    known = residual_moves(inputs, K, m)
    E, t0, own0 = between_window_excess(f, y_mean, V, K)
    E1, t1, own1 = between_window_excess(f, y_mean, V, K, known=known)
    H = design_rows(f)
    S = V + E
    W = np.linalg.inv(S)
    HtW = np.einsum("wai,wab->wib", H, W)
    Ninv = np.linalg.inv(np.einsum("wib,wbj->ij", HtW, H))
    meat = np.einsum("wib,wbc,wjc->ij", HtW, V + E1, HtW)
    cov = Ninv @ meat @ Ninv
    clipped = ["pose scatter"] if t0 > 0 and t1 == 0 else []
    clipped += [
        f"own excess, channel {c}" for c, a, b in zip(CHANNELS, own0, own1, strict=True) if a > 0 and b == 0
    ]
    return TypeA(
        cov=0.5 * (cov + cov.T),
        cov_fit=0.5 * (Ninv + Ninv.T),
        weights_cov=S,
        pose_var=(t0, t1),
        own_var=np.array([own0, own1]),
        clipped=tuple(clipped),
    )
