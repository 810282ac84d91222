"""Covariance of stacked window means with a slow wander between windows, solved in O(m).

Observation vector z (3m,), window-major (index 3·w + i is channel i of window w). Its
covariance (channel units²) is

    C = blockdiag_w(B_w) + Σ_i τ_i² (P ⊗ e_i e_iᵀ),   P_ww' = exp(−|t_w − t_w'| / T_c)

with B_w (3, 3) everything that belongs to one window alone (the window mean's own noise,
a pose error, a free orientation) and, per channel i, a slow wander s_i(t) of variance τ_i²
and correlation time T_c: a first-order Gauss-Markov (Ornstein-Uhlenbeck) process sampled
at the window times t_w (T_c = 0: independent from window to window, P = I).

A dense Cholesky factor of C costs O(m³) and O(m²) memory. Here C = B + A S Aᵀ, with
B = blockdiag(B_w), A the (3m, k·m) selector of the k channels with τ_i² > 0 and S the
covariance of the k·m wander states. The wander is Markov in time, so S⁻¹ is tridiagonal
per channel (Rybicki & Press, ApJ 398 (1992) 169, for the exponential kernel): in time
order, with ρ_w = exp(−(t_w − t_{w−1}) / T_c) and q_w = 1 − ρ_w²,

    τ² (S⁻¹)_ww = [w > 0] / q_w + [w < m−1] ρ_{w+1}² / q_{w+1} + [w = 0],
    τ² (S⁻¹)_w,w+1 = −ρ_{w+1} / q_{w+1},
    ln|S_i| = m ln τ_i² + Σ_{w>0} ln q_w.

By the Woodbury identity and the matrix determinant lemma (Harville, "Matrix Algebra From
a Statistician's Perspective", 1997, §18.1-18.2)

    C⁻¹ = B⁻¹ − B⁻¹ A M⁻¹ Aᵀ B⁻¹,   ln|C| = ln|B| + ln|S| + ln|M|,   M = S⁻¹ + Aᵀ B⁻¹ A,

and M, ordered window-major, is a banded matrix of half-bandwidth k ≤ 3, factored by
LAPACK's banded Cholesky (``scipy.linalg.cholesky_banded``). Every product with C⁻¹ and
ln|C| then costs O(m k³), and nothing m × m is ever formed. The diagonal blocks of C⁻¹
(for the BLUP of per-window effects) come from the block-tridiagonal selected inversion
of M (Takahashi's recursion; Rybicki & Hummer, J. Comput. Phys. 196 (2004) 1), also O(m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.linalg import cho_solve_banded, cholesky_banded
from scipy.linalg.lapack import dtbtrs

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class WindowCovariance:
    """C of the module docstring.

    :param blocks: (m, 3, 3) per-window covariance B_w (channel units²), symmetric positive definite.
    :param tau2: (3,) slow-wander variance per channel (channel units²), ≥ 0.
    :param corr_time_s: its correlation time T_c (s); ≤ 0: independent between windows.
    :param mid_s: (m,) window times (s); any order, distinct when ``corr_time_s`` > 0.
    :param blocks_inverse: (m, 3, 3) B_w⁻¹ if already known (``invert_blocks``), so that
        covariances that differ only in the wander share that work.
    :param blocks_logdet: Σ_w ln|B_w| with ``blocks_inverse``.
    """

    blocks: FloatArray
    tau2: FloatArray
    corr_time_s: float
    mid_s: FloatArray
    blocks_inverse: FloatArray | None = None
    blocks_logdet: float | None = None

    @property
    def m(self) -> int:
        """Number of windows."""
        return int(self.blocks.shape[0])

    @property
    def n(self) -> int:
        """Number of scalar observations, 3·m."""
        return 3 * self.m

    def dense(self) -> FloatArray:
        """(3m, 3m) C as a dense matrix (for checks and small m only)."""
        m = self.m
        C = np.zeros((3 * m, 3 * m))
        for w in range(m):
            C[3 * w : 3 * w + 3, 3 * w : 3 * w + 3] = self.blocks[w]
        if self.corr_time_s > 0:
            P = np.exp(-np.abs(self.mid_s[:, None] - self.mid_s[None, :]) / self.corr_time_s)
        else:
            P = np.eye(m)
        for i in range(3):
            if self.tau2[i] > 0:
                C[i::3, i::3] += self.tau2[i] * P
        return C

    def diagonal(self) -> FloatArray:
        """(3m,) diagonal of C."""
        return (np.diagonal(self.blocks, axis1=1, axis2=2) + np.maximum(self.tau2, 0.0)[None, :]).reshape(-1)

    def factor(self) -> CovarianceFactor:
        """The O(m) factorisation of C.

        :raises ValueError: a block B_w or M not positive definite, or two windows at the
            same time with a correlated wander.
        """
        return CovarianceFactor(self)


@dataclass(frozen=True)
class FixedQuadratic:
    """What :meth:`CovarianceFactor.quadratic` needs of a fixed Y (3m, q) and fixed blocks
    B_w: both terms that do not depend on the wander, in the windows' time order. Covariances
    that differ only in the wander (a noise search) share it (:func:`fixed_quadratic`).

    :param order: (m,) the time order of the windows, ``np.argsort(mid_s, kind="stable")``.
    :param binv_y: (m, 3, q) B⁻¹ Y, its windows in that order.
    :param yby: (q, q) Yᵀ B⁻¹ Y, summed in that order.
    """

    order: npt.NDArray[np.intp]
    binv_y: FloatArray
    yby: FloatArray


def fixed_quadratic(Y: FloatArray, binv_y: FloatArray, mid_s: FloatArray) -> FixedQuadratic:
    """:class:`FixedQuadratic` of Y (3m, q) or (3m,), B⁻¹ Y of the same shape and the window
    times ``mid_s`` (m,) (s)."""
    m = np.asarray(mid_s).shape[0]
    order = np.argsort(mid_s, kind="stable")
    Ys = np.asarray(Y, dtype=float).reshape(m, 3, -1)[order]
    return _sorted_quadratic(order, Ys, np.asarray(binv_y, dtype=float).reshape(m, 3, -1)[order])


def _sorted_quadratic(order: npt.NDArray[np.intp], Ys: FloatArray, W: FloatArray) -> FixedQuadratic:
    """:class:`FixedQuadratic` from Y and B⁻¹ Y (m, 3, q), both already in time ``order``."""
    m, q = W.shape[0], W.shape[2]
    # skinny Gram products by einsum: no BLAS threads to wake for a (q, q) result
    Q = np.einsum("nq,nr->qr", Ys.reshape(3 * m, q), W.reshape(3 * m, q), optimize=False)
    return FixedQuadratic(order=order, binv_y=W, yby=Q)


def invert_blocks(blocks: FloatArray) -> tuple[FloatArray, float]:
    """B_w⁻¹ (m, 3, 3) and Σ_w ln|B_w| of symmetric positive-definite blocks (m, 3, 3).

    :raises ValueError: a block is not positive definite (the window is named by index).
    """
    B = 0.5 * (blocks + np.transpose(blocks, (0, 2, 1)))
    try:
        Lb = np.linalg.cholesky(B)
    except np.linalg.LinAlgError as exc:
        bad = [w for w in range(B.shape[0]) if np.any(np.linalg.eigvalsh(B[w]) <= 0)]
        raise ValueError(
            f"noise covariance is not positive definite (own block of window {bad[:1]})"
        ) from exc
    logdet = 2.0 * float(np.sum(np.log(np.diagonal(Lb, axis1=1, axis2=2))))
    return np.asarray(np.linalg.inv(B), dtype=np.float64), logdet


class CovarianceFactor:
    """Factorisation of a :class:`WindowCovariance`: C⁻¹ Y and ln|C| in O(m) (module docstring)."""

    def __init__(self, cov: WindowCovariance) -> None:
        self.cov = cov
        m = cov.m
        self._order = np.argsort(cov.mid_s, kind="stable")
        if cov.blocks_inverse is not None and cov.blocks_logdet is not None:
            self._Binv, logdet = cov.blocks_inverse[self._order], float(cov.blocks_logdet)
        else:
            self._Binv, logdet = invert_blocks(cov.blocks[self._order])
        tau2 = np.asarray(cov.tau2, dtype=float)
        self._act = np.flatnonzero(tau2 > 0)
        k = self._act.size
        self._k = k
        self._cb: FloatArray | None = None
        if k:
            t2 = tau2[self._act]
            diag = np.ones((m, k)) / t2[None, :]
            off = np.zeros((max(m - 1, 0), k))
            logdet_s = m * float(np.sum(np.log(t2)))
            if cov.corr_time_s > 0 and m > 1:
                dt = np.diff(np.asarray(cov.mid_s, dtype=float)[self._order])
                if np.any(dt <= 0):
                    raise ValueError("two windows share a time: a correlated wander cannot be ordered")
                x = dt / cov.corr_time_s
                rho = np.exp(-x)
                q = -np.expm1(-2.0 * x)
                diag[1:] = (1.0 / q)[:, None] / t2[None, :]
                diag[:-1] += (rho**2 / q)[:, None] / t2[None, :]
                off = (-rho / q)[:, None] / t2[None, :]
                logdet_s += k * float(np.sum(np.log(q)))
            Mw = self._Binv[:, self._act][:, :, self._act].copy()
            Mw[:, np.arange(k), np.arange(k)] += diag
            self._Mw, self._off = Mw, off
            ab = np.zeros((k + 1, m * k))
            for a in range(k):
                for b in range(a, k):
                    ab[k + a - b, b::k] = Mw[:, a, b]
            if m > 1:
                for a in range(k):
                    ab[0, k + a :: k] = off[:, a]
            try:
                self._cb = cholesky_banded(ab, lower=False, check_finite=False)
            except np.linalg.LinAlgError as exc:
                raise ValueError("noise covariance is not positive definite (slow wander)") from exc
            logdet += logdet_s + 2.0 * float(np.sum(np.log(self._cb[k])))
        self.logdet = logdet

    def _active_rows(self, W: FloatArray) -> FloatArray:
        """W[:, act, :] of W (m, 3, q): the channels with a wander (all three: W itself)."""
        return W if self._k == 3 else np.take(W, self._act, axis=1)

    def _to_sorted(self, Y: FloatArray) -> FloatArray:
        return Y.reshape(self.cov.m, 3, -1)[self._order]

    def solve(self, Y: FloatArray) -> FloatArray:
        """C⁻¹ Y for Y of shape (3m,) or (3m, q)."""
        Yv = np.asarray(Y, dtype=float)
        vec = Yv.ndim == 1
        Ys = self._to_sorted(Yv)
        W = np.matmul(self._Binv, Ys)
        if self._k:
            assert self._cb is not None
            m, k, q = self.cov.m, self._k, Ys.shape[2]
            G = self._active_rows(W).reshape(m * k, q)
            H = cho_solve_banded((self._cb, False), G, check_finite=False).reshape(m, k, q)
            W = W - np.matmul(self._Binv[:, :, self._act], H)
        out = np.empty_like(W)
        out[self._order] = W
        return np.asarray(out.reshape(-1) if vec else out.reshape(3 * self.cov.m, -1), dtype=float)

    def quadratic(self, Y: FloatArray, binv_y: FloatArray | None = None) -> FloatArray:
        """Yᵀ C⁻¹ Y (q, q) for Y (3m, q), without forming C⁻¹ Y:
        Yᵀ B⁻¹ Y − Gᵀ M⁻¹ G with G = Aᵀ B⁻¹ Y (module docstring).

        :param binv_y: B⁻¹ Y (3m, q) if already known (it does not depend on the wander).
        """
        Yv = np.asarray(Y, dtype=float).reshape(3 * self.cov.m, -1)
        Ys = self._to_sorted(Yv)
        if binv_y is None:
            W = np.matmul(self._Binv, Ys)
        else:
            W = self._to_sorted(np.asarray(binv_y, dtype=float).reshape(Yv.shape))
        return self.quadratic_fixed(_sorted_quadratic(self._order, Ys, W))

    def quadratic_fixed(self, fixed: FixedQuadratic) -> FloatArray:
        """Yᵀ C⁻¹ Y (q, q) from the wander-free parts of Y (:class:`FixedQuadratic`, made with
        this covariance's window times and blocks): only Gᵀ M⁻¹ G is computed here.

        :raises ValueError: ``fixed`` was made with another time order of the windows.
        """
        if not np.array_equal(fixed.order, self._order):
            raise ValueError("the fixed quadratic was made for other window times")
        W, Q = fixed.binv_y, fixed.yby
        if self._k:
            assert self._cb is not None
            m, q = self.cov.m, W.shape[2]
            G = self._active_rows(W).reshape(m * self._k, q)
            # Gᵀ M⁻¹ G = Hᵀ H with M = Uᵀ U and H = U⁻ᵀ G: one banded triangular solve
            H, info = dtbtrs(self._cb, G, uplo="U", trans="T")
            if info != 0:
                raise ValueError("noise covariance is not positive definite (slow wander)")
            Q = Q - H.T @ H
        return np.asarray(0.5 * (Q + Q.T), dtype=float)

    def inverse_diagonal_blocks(self) -> FloatArray:
        """(m, 3, 3) diagonal blocks (C⁻¹)_ww in the original window order."""
        out = self._Binv.copy()
        if self._k:
            m, k = self.cov.m, self._k
            Sig_inv = np.empty((m, k, k))
            S = self._Mw[0]
            Sig_inv[0] = np.linalg.inv(S)
            for w in range(1, m):  # forward elimination: Σ_w = D_w − E Σ_{w−1}⁻¹ E (E diagonal)
                e = self._off[w - 1]
                S = self._Mw[w] - e[:, None] * Sig_inv[w - 1] * e[None, :]
                Sig_inv[w] = np.linalg.inv(S)
            G = np.empty((m, k, k))
            G[m - 1] = Sig_inv[m - 1]
            for w in range(m - 2, -1, -1):  # G_w = Σ_w⁻¹ + Σ_w⁻¹ E G_{w+1} E Σ_w⁻¹
                SE = Sig_inv[w] * self._off[w][None, :]
                G[w] = Sig_inv[w] + SE @ G[w + 1] @ SE.T
            Ba = self._Binv[:, :, self._act]
            out = out - np.einsum("wia,wab,wjb->wij", Ba, G, Ba)
        res = np.empty_like(out)
        res[self._order] = out
        return res
