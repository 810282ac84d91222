"""Score statistics of the moving library's candidates, with the recording's own serially
correlated noise (``library_motion_search`` uses them).

A candidate a (a monomial x on channel i) against the current model's residual e, with a
projected beyond the model's Jacobian J (the catalogue's parameters and the library terms
already in), W = diag(1/σ̂_c²):

    ã = a − J β,  β = (JᵀWJ)⁺ JᵀW a,   U = ãᵀ W e,   ĉ = U / ãᵀWã.

Samples are not independent (the bias wander, the motion's unmodelled remainder), so U's
variance is the Newey-West long-run variance (Econometrica 55 (1987) 703) of its block sums
over the dynamic fit's score blocks (``dynamic_batch``: the recording in 50 blocks of ≥ 1 s,
Bartlett weights to ``NW_LAGS`` lags, the small-sample factor n_b/(n_b − p)), the block sums
taken under the alternative (s_b − ĉ Σ_b ãᵀWã: the candidate's own fit out of the residual,
else a true term inflates its own variance), and never less than the white-noise value
ãᵀWã (as the fit's own sandwich):

    T = U² / max(V_NW, ãᵀWã),   σ(ĉ) = √max(V_NW, ãᵀWã) / ãᵀWã.

T is judged against F(1, ν), ν = n_b / Σ_{|k|≤L} w_k² the Satterthwaite degrees of freedom of
a Bartlett long-run variance from n_b blocks (Var Ŝ / S² ≈ 2 Σ w_k² / n_b, Newey & West,
Rev. Econ. Stud. 61 (1994) 631): the effective sample size is the number of blocks, not of
samples. Also per candidate: its relative leverage √(ãᵀWã / aᵀWa), and the share cos² of
its signature beyond the model that lies in the span of the catalogue's terms not in the
model. The projections use every ``stride``-th sample (at most ``Thresholds.motion_subsample``: J and x are
smooth), the scores every sample, in chunks of ``Thresholds.motion_chunk_samples``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.diagnosis.library import Base
from bench.diagnosis.library_motion import MotionTerm, base_values
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import BLOCK_S, NW_LAGS, TARGET_BLOCKS, DynamicFit
from bench.estimation.dynamic_model import ModelSpec, predict
from bench.estimation.motion_data import MotionData

FloatArray = np.ndarray
KEEP_VALUES_BYTES = 1 << 27
"""The monomials' values a search keeps between its steps (bytes): the whole recording's up to
this size (a 50 Hz rate-1axis: 14 600 samples x 1 068 monomials, 125 MB), the first chunks' beyond it; the
others are formed again at each step, as they all were before (docs/benchmarks.md)."""
SLOW_TRENDS = ("t", "temp")
"""Slow trends a bias wander can make over one run: their powers up to the third on each
channel span what a term must not mostly be (``library_motion``, "slow")."""


@dataclass(frozen=True)
class Stats:
    """Per channel c: U (M,), V (M,) = max(NW, white), P (M, M) projected Gram, lev (M,), and the
    shares cos² of each signature beyond the model within the catalogue's span and within the
    slow trends' (M,)."""

    U: list[FloatArray]
    V: list[FloatArray]
    P: list[FloatArray]
    lev: list[FloatArray]
    cat_cos2: list[FloatArray]
    slow_cos2: list[FloatArray]
    scale: FloatArray
    n_blocks: int
    p: int


def _blocks(m: MotionData) -> tuple[np.ndarray, int]:
    span = float(m.t_s[-1] - m.t_s[0])
    block = max(BLOCK_S, span / TARGET_BLOCKS)
    blk = np.floor((m.t_s - m.t_s[0]) / block).astype(np.int64)
    ids, inv = np.unique(blk[m.valid], return_inverse=True)
    out = np.full(m.n, -1, dtype=np.int64)
    out[m.valid] = inv
    return out, int(ids.size)


def lib_columns(terms: list[MotionTerm], vals: dict[str, FloatArray], idx: np.ndarray) -> FloatArray:
    """(len(idx), 3, k) columns of library terms (x_k on channel i_k)."""
    out = np.zeros((idx.size, 3, len(terms)))
    for k, t in enumerate(terms):
        out[:, t.channel, k] = base_values(vals, t.factors, idx)
    return out


def solve_scaled(H: FloatArray, B: FloatArray) -> FloatArray:
    """H⁺ B, H scaled to unit diagonal first (a pseudo-inverse: J may hold dependent columns)."""
    d = np.sqrt(np.maximum(np.diag(H), 1e-300))
    Hi = np.linalg.pinv(H / np.outer(d, d), rcond=1e-12, hermitian=True)
    return np.asarray((Hi @ (B / d[:, None])) / d[:, None])


def _nw(S: FloatArray) -> FloatArray:
    """Column-wise Newey-West long-run variance of block sums (nb, M), Bartlett weights."""
    v = np.sum(S * S, axis=0)
    for k in range(1, NW_LAGS + 1):
        v += 2.0 * (1.0 - k / (NW_LAGS + 1.0)) * np.sum(S[:-k] * S[k:], axis=0)
    return np.asarray(v)


def satterthwaite_dof(n_blocks: int) -> float:
    """ν = n_b / Σ_{|k|≤L} w_k², Bartlett weights w_k = 1 − |k|/(L+1) (module docstring)."""
    s = 1.0 + 2.0 * sum((1.0 - k / (NW_LAGS + 1.0)) ** 2 for k in range(1, NW_LAGS + 1))
    return n_blocks / s


@dataclass(frozen=True)
class Design:
    """The monomials of one search and what does not change between its steps: the index
    triples of their factors into the base matrix (``ones`` pads lower degrees), the samples
    used, the subsample for projections, its scaled values Xs, their RMS and Gram matrix, and
    the score blocks."""

    index: np.ndarray
    names: tuple[str, ...]
    idx: np.ndarray
    stride: int
    sub: np.ndarray
    Xs: FloatArray
    scale: FloatArray
    XtX: FloatArray
    blk: np.ndarray
    nb: int
    slow_names: tuple[str, ...] = ()
    kept: dict[int, FloatArray] = field(default_factory=dict, compare=False, repr=False)
    asked: set[int] = field(default_factory=set, compare=False, repr=False)

    def values(self, base: BaseColumns, rows: np.ndarray) -> FloatArray:
        """(len(rows), M) scaled monomials at ``rows`` from the (n, n_bases + 1) base matrix."""
        b = base[rows]
        return np.asarray(b[:, self.index[0]] * b[:, self.index[1]] * b[:, self.index[2]] / self.scale)

    def chunk_values(self, base: BaseColumns, start: int, rows: np.ndarray) -> FloatArray:
        """:meth:`values` at the chunk of the used samples that begins at ``start`` (``rows``:
        ``idx[start:start + chunk]``). A search asks for the same chunks at every step (only the
        residual they are summed against changes): from a chunk's second asking on, it is kept
        while the kept chunks stay within :data:`KEEP_VALUES_BYTES` (a search that stops at its
        first step, a clean recording's, keeps nothing)."""
        got = self.kept.get(start)
        if got is not None and got.shape[0] == rows.size:
            return got
        X = self.values(base, rows)
        if start in self.asked and sum(v.nbytes for v in self.kept.values()) + X.nbytes <= KEEP_VALUES_BYTES:
            self.kept[start] = X
        self.asked.add(start)
        return X


@dataclass(frozen=True)
class BaseColumns:
    """The (n, n_bases + 1) base matrix [x_1 … x_B, 1] by reference to the (n,) base values: rows
    are gathered when asked for, so a search holds no second copy of the bases."""

    cols: tuple[FloatArray, ...]

    def __getitem__(self, rows: np.ndarray) -> FloatArray:
        """(len(rows), n_bases + 1) the base matrix's ``rows``."""
        return np.column_stack([*(c[rows] for c in self.cols), np.ones(rows.size)])


def _base_matrix(vals: dict[str, FloatArray], names: tuple[str, ...]) -> BaseColumns:
    return BaseColumns(tuple(vals[k] for k in names))


def design(
    m: MotionData,
    monos: list[tuple[Base, ...]],
    vals: dict[str, FloatArray],
    th: Thresholds = THRESHOLDS,
) -> tuple[Design, BaseColumns]:
    names = tuple(dict.fromkeys(b.name for f in monos for b in f))
    pos = {n: k for k, n in enumerate(names)}
    one = len(names)
    index = np.array([[pos[b.name] for b in f] + [one] * (3 - len(f)) for f in monos], dtype=np.int64).T
    base = _base_matrix(vals, names)
    idx = np.flatnonzero(m.valid)
    stride = max(1, idx.size // th.motion_subsample)
    sub = idx[::stride]
    bs = base[sub]
    Xs = bs[:, index[0]] * bs[:, index[1]] * bs[:, index[2]]
    scale = np.sqrt(np.mean(Xs * Xs, axis=0))
    scale = np.where(scale > 0, scale, 1.0)
    Xs = Xs / scale
    blk, nb = _blocks(m)
    slow = tuple(k for k in SLOW_TRENDS if k in vals)
    d = Design(index, names, idx, stride, sub, Xs, scale, stride * (Xs.T @ Xs), blk, nb, slow)
    return d, base


def _share_within(
    Js: FloatArray,
    Jx: FloatArray,
    Xs: FloatArray,
    XtX: FloatArray,
    P: list[FloatArray],
    w: FloatArray,
    stride: int,
) -> list[FloatArray]:
    """Per channel, cos² of each monomial's signature beyond [Js] that lies in the span of Jx beyond it."""
    Ja = np.concatenate([Js, Jx], axis=2)
    Ha = stride * sum(w[c] * Ja[:, c, :].T @ Ja[:, c, :] for c in range(3))
    out = []
    for c in range(3):
        Ba = stride * w[c] * Ja[:, c, :].T @ Xs
        pa = w[c] * np.diag(XtX) - np.sum(Ba * solve_scaled(Ha, Ba), axis=0)
        out.append(1.0 - np.clip(pa, 0.0, None) / np.maximum(np.diag(P[c]), 1e-300))
    return out


def scores(
    m: MotionData,
    y_adj: FloatArray,
    fit: DynamicFit,
    g: float,
    lever: FloatArray,
    aug: list[MotionTerm],
    des: Design,
    base: BaseColumns,
    vals: dict[str, FloatArray],
    catalogue: tuple[ModelSpec, FloatArray] | None,
    *,
    shares: bool = True,
    th: Thresholds = THRESHOLDS,
) -> Stats:
    """Scores, HAC variances and projections of every monomial on every channel (module docstring).

    ``shares``: also the shares of each signature in the catalogue's and the slow trends' span
    (zeros otherwise; a search computes them at its first step and keeps them).
    """
    w = 1.0 / np.maximum(fit.noise_sigma, 1e-300) ** 2
    idx, stride, sub, Xs, XtX, M = des.idx, des.stride, des.sub, des.Xs, des.XtX, des.Xs.shape[1]
    _, Js = predict(fit.theta, m.take(sub, rates=fit.spec.needs_rates), fit.spec, g, lever, jacobian=True)
    assert Js is not None
    Js = np.concatenate([Js, lib_columns(aug, vals, sub)], axis=2)
    p = Js.shape[2]
    H = stride * sum(w[c] * Js[:, c, :].T @ Js[:, c, :] for c in range(3))
    Bc = [stride * w[c] * Js[:, c, :].T @ Xs for c in range(3)]
    Beta = [solve_scaled(H, Bc[c]) for c in range(3)]
    cat_cos2 = [np.zeros(M) for _ in range(3)]
    P = [w[c] * XtX - Bc[c].T @ Beta[c] for c in range(3)]
    if shares and catalogue is not None:
        _, Jx = predict(
            catalogue[1], m.take(sub, rates=catalogue[0].needs_rates), catalogue[0], g, lever, jacobian=True
        )
        assert Jx is not None
        cat_cos2 = _share_within(Js, Jx, Xs, XtX, P, w, stride)
    slow_cos2 = [np.zeros(M) for _ in range(3)]
    if shares and des.slow_names:
        zs = [
            (vals[k][sub] - vals[k][sub].mean()) / max(float(np.ptp(vals[k][sub])), 1e-300)
            for k in des.slow_names
        ]
        S1 = np.column_stack([z**j for z in zs for j in (1, 2, 3)])
        Jsl = np.zeros((sub.size, 3, 3 * S1.shape[1]))
        for c in range(3):
            Jsl[:, c, c * S1.shape[1] : (c + 1) * S1.shape[1]] = S1
        slow_cos2 = _share_within(Js, Jsl, Xs, XtX, P, w, stride)
    blk, nb = des.blk, des.nb
    SX = [np.zeros((nb, M)) for _ in range(3)]
    SJ = [np.zeros((nb, p)) for _ in range(3)]
    chunk = th.motion_chunk_samples
    for a in range(0, idx.size, chunk):
        sel = idx[a : a + chunk]
        raw, J = predict(
            fit.theta, m.take(sel, rates=fit.spec.needs_rates), fit.spec, g, lever, jacobian=True
        )
        assert J is not None
        J = np.concatenate([J, lib_columns(aug, vals, sel)], axis=2)
        e = y_adj[sel] - raw
        X = des.chunk_values(base, a, sel)
        b = blk[sel]
        starts = np.concatenate([[0], np.flatnonzero(np.diff(b)) + 1])
        ub = b[starts]
        for c in range(3):
            we = w[c] * e[:, c]
            SX[c][ub] += np.add.reduceat(X * we[:, None], starts, axis=0)
            SJ[c][ub] += np.add.reduceat(J[:, c, :] * we[:, None], starts, axis=0)
    small = nb / (nb - p) if nb > p + 1 else np.inf
    SJall = SJ[0] + SJ[1] + SJ[2]
    bsub = blk[sub]
    U, V, lev = [], [], []
    for c in range(3):
        S = SX[c] - SJall @ Beta[c]
        white = np.clip(np.diag(P[c]), 0.0, None)
        u = S.sum(axis=0)
        # the block scores under the alternative (the term's own fit taken out of the residual):
        # s_b − ĉ Σ_b ãᵀWã, the block sums of ãᵀWã from the subsample
        q = np.zeros_like(Xs)
        for k in range(3):
            proj = Js[:, k, :] @ Beta[c]
            q += w[k] * ((Xs - proj) if k == c else proj) ** 2
        Q = np.zeros((nb, M))
        starts = np.concatenate([[0], np.flatnonzero(np.diff(bsub)) + 1])
        Q[bsub[starts]] = stride * np.add.reduceat(q, starts, axis=0)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            S = S - (u / white)[None, :] * Q
            v = np.where(white > 0, np.maximum(_nw(S) * small, white), np.inf)
        U.append(u)
        V.append(np.where(np.isfinite(v), v, np.inf))
        lev.append(np.sqrt(white / np.maximum(w[c] * np.diag(XtX), 1e-300)))
    return Stats(U, V, P, lev, cat_cos2, slow_cos2, des.scale, nb, p)
