"""Whether a moving recording's final residual is coherent over seconds: a von Neumann test on
its 1 s block means, per channel.

A misfit the model does not hold (a bias step, a slow disturbance, a term outside every library)
moves neighbouring block means together; the recording's own noise, whatever its level and its
colour within a second, leaves them independent once the wander's slow part is taken out. Per
channel c, with b_k the block means of the final residual r (channel units), n_k their sample
counts and z_k = √n_k · b_k (equal variance under white or short-memory noise):

    ẑ = M z,   M = I − Q Qᵀ,   Q an orthonormal basis of √n_k · [1, f̄_x, f̄_y, f̄_z, P_1(s), …, P_D(s)]

(f̄ the block means of the final model's specific force: what bias and K absorb; P_j Legendre
polynomials in the block's time s ∈ [−1, 1], D = ``Thresholds.coherence_trend_degree``: the
slow part of a bias wander over one run), and the von Neumann ratio (von Neumann 1941; the
Durbin–Watson statistic of the projected block means, Durbin & Watson 1950)

    R = Σ_k (ẑ_{k+1} − ẑ_k)² / Σ_k ẑ_k² = εᵀ M A M ε / εᵀ M ε,   A = DᵀD (D the first difference).

Under H0 (z_k independent, equal variance) R does not depend on that variance and is independent
of εᵀMε (Pitman–Koopmans), so its moments are exact: E[R] = tr(MA)/m and
E[R²] = (tr(MA)² + 2 tr((MA)²)) / (m(m + 2)), m = nb − rank Q. R/λ_max (λ_max = 4) is referred
to the Beta distribution with those two moments (Durbin & Watson 1971's approximation); a coherent
misfit lowers R (the lower tail), at ``Thresholds.unexplained_alpha`` / 3 per channel. The traces
are formed from A Q (A tridiagonal), O(nb · rank²).

Blocks are compared with their neighbours in the order they were kept; a gap in the recording
puts two blocks that are not adjacent in time side by side (one difference of nb − 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre
from scipy.stats import beta as beta_dist

FloatArray = np.ndarray


@dataclass(frozen=True)
class Coherence:
    """Per channel (3,): the ratio R, its expectation under H0 and the lower-tail p value."""

    ratio: FloatArray
    expected: FloatArray
    p_value: FloatArray
    n_blocks: int


def trend_basis(n_blocks: int, degree: int) -> FloatArray:
    """(n_blocks, degree) Legendre polynomials P_1 … P_degree over s ∈ [−1, 1] along the blocks."""
    s = np.linspace(-1.0, 1.0, n_blocks) if n_blocks > 1 else np.zeros(1)
    return np.column_stack([legendre.legval(s, np.eye(degree + 1)[j]) for j in range(1, degree + 1)])


def _diff_op(x: FloatArray) -> FloatArray:
    """A x for A = DᵀD (nb × nb tridiagonal: 1, 2, …, 2, 1 on the diagonal, −1 beside it)."""
    d = np.diff(x, axis=0)
    out = np.zeros_like(x)
    out[:-1] -= d
    out[1:] += d
    return out


def von_neumann_moments(Q: FloatArray) -> tuple[float, float, int]:
    """(E[R], Var[R], m) under H0 for the projector M = I − Q Qᵀ (Q (nb, k) orthonormal)."""
    nb, k = Q.shape
    m = nb - k
    AQ = _diff_op(Q)
    tr_A = 2.0 * (nb - 1)
    tr_A2 = 6.0 * nb - 8.0 if nb >= 2 else 0.0  # Σ diag² + Σ off-diag² = (4(nb − 2) + 2) + 2(nb − 1)
    QAQ = Q.T @ AQ
    tr_MA = tr_A - float(np.trace(QAQ))
    # tr((MA)²) = tr(A²) − 2 tr(Qᵀ A² Q) + tr((Qᵀ A Q)²)
    tr_MA2 = tr_A2 - 2.0 * float(np.sum(AQ * AQ)) + float(np.sum(QAQ * QAQ.T))
    mean = tr_MA / m
    second = (tr_MA**2 + 2.0 * tr_MA2) / (m * (m + 2.0))
    return mean, max(second - mean * mean, 1e-300), m


def block_coherence(
    block_means: FloatArray, counts: FloatArray, nuisance: FloatArray, degree: int
) -> Coherence | None:
    """The von Neumann test of the module docstring on every channel.

    :param block_means: (nb, 3) block means of the final residual (channel units).
    :param counts: (nb,) samples per block; :param nuisance: (nb, q) block columns the model absorbs
        ([1, f̄_x, f̄_y, f̄_z]); :param degree: the trend's Legendre degree D.
    :returns: ``None`` when fewer than 3 blocks remain beyond the basis.
    """
    nb = block_means.shape[0]
    w = np.sqrt(np.asarray(counts, dtype=float))
    basis = np.column_stack([nuisance, trend_basis(nb, degree)]) * w[:, None]
    U, s, _ = np.linalg.svd(basis, full_matrices=False)
    Q = U[:, s > s.max() * 1e-10]
    if nb - Q.shape[1] < 3:
        return None
    mean, var, _ = von_neumann_moments(Q)
    top = 4.0  # DᵀD's eigenvalues lie in [0, 4] (Gershgorin): so does R
    mu, s2 = mean / top, var / top**2
    common = mu * (1.0 - mu) / s2 - 1.0
    a, b = mu * common, (1.0 - mu) * common
    z = block_means * w[:, None]
    zh = z - Q @ (Q.T @ z)
    num = np.sum(np.diff(zh, axis=0) ** 2, axis=0)
    den = np.maximum(np.sum(zh * zh, axis=0), 1e-300)
    ratio = num / den
    p = np.asarray(beta_dist.cdf(ratio / top, a, b), dtype=float)
    return Coherence(ratio=ratio, expected=np.full(3, mean), p_value=p, n_blocks=nb)
