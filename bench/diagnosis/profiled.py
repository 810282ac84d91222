"""A candidate whose column depends on a parameter not linear in the model (a thermal lag's time
constant τ): the parameter profiled on a grid, the gate sized for the search.

For a family a(v) (``effects.base.Family``) and the current design X under the current noise C,
the statistic of v is the Δχ² of adding a(v) alone, LR(v) = (aᵀPy)² / aᵀPa with
P = C⁻¹ − C⁻¹X(XᵀC⁻¹X)⁻¹XᵀC⁻¹ (``model_state.whitened_lr``); the family's statistic is its
maximum over the grid, refined by a parabola through the best point and its neighbours in ln v.

**Gate.** Under no effect, LR(v) = Z(v)² with Z a unit Gaussian process in v, and the maximum
of Z² over the grid is not χ²₁. Davies' bound (Biometrika 64 (1977) 247; 74 (1987) 33) for
the upcrossings of |Z| gives

    P(max_v LR(v) > u) ≤ P(χ²₁ > u) + (L / π)·e^{−u/2},

L the length of the curve the whitened, projected, normalised columns u(v) = P^{1/2}a(v)/‖·‖
trace on the unit sphere, Σ_k arccos |cos(u_k, u_{k+1})| over the grid. The gate u solves the
bound = α; the candidate then counts as ``tries`` = α / P(χ²₁ > u) independent candidates
(its effective number of independent v values), and its F gate is taken at α / tries
(``column_step``). L = 0 (one value, or every column alike) gives the χ²₁ gate.

**Reduction.** The family reduces to another effect at the null column (a lag of 0: the plain
temperature coefficient). The family is claimed only where its best v beats the null column
by the χ²₁ gate at ``Thresholds.false_alarm``: LR(v̂) − LR(null) > χ²₁(1 − false_alarm) (the
null's LR taken as 0 where its column has no leverage beyond X, e.g. the plain effect already
in the model). One question per claim, not shared over the step's candidates: it chooses the
form of an effect the candidate's own gate already admits (a lag, or none), it does not admit
one; as a boundary test (v ≥ 0) its level is at most that. Otherwise the family is noted as
the reduced effect and left to that effect's own candidate.

**Sigmas.** The fixed candidate is the column a(v̂) with v held; the joint information of
(c, v) at v̂, J = [a(v̂), c·∂a/∂v] (central difference, a tenth of the grid's step), gives the
coefficient's variance with v free and v's own (``Family.at``).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import numpy.typing as npt
from scipy.optimize import brentq
from scipy.stats import chi2

from bench.diagnosis.effects import Candidate, pose_response
from bench.diagnosis.effects.base import Family, FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import NoiseParams, window_covariance
from bench.diagnosis.model_state import design
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


def davies_gate(alpha: float, length: float) -> float:
    """The level u with P(χ²₁ > u) + (L/π)·e^{−u/2} = α (module docstring)."""
    lo = float(chi2.isf(alpha, 1))
    if length <= 0:
        return lo

    def excess(u: float) -> float:
        return float(chi2.sf(u, 1)) + length / math.pi * math.exp(-u / 2.0) - alpha

    hi = lo
    while excess(hi) > 0:
        hi = 2.0 * hi + 1.0
    return float(brentq(excess, lo, hi, xtol=1e-10))


def effective_tries(alpha: float, length: float) -> float:
    """α / P(χ²₁ > u) at Davies' gate u: the search's effective number of independent values."""
    return float(alpha / chi2.sf(davies_gate(alpha, length), 1))


def projected_gram(
    ev: StaticEvidence,
    X: FloatArray,
    A: FloatArray,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(aᵀPy (N,), AᵀPA (N, N), aᵀC⁻¹a (N,)) of the columns A (3m, N) beyond X (module docstring)."""
    solver = window_covariance(ev.V, ev.mid_s, noise, pose_response(ev, K), fixed).factor()
    y = ev.y.reshape(-1)
    Ci_X, Ci_y, Ci_A = solver.solve(X), solver.solve(y), solver.solve(A)
    M = X.T @ Ci_X
    XtCiA = X.T @ Ci_A
    aPy = A.T @ Ci_y - XtCiA.T @ np.linalg.solve(M, X.T @ Ci_y)
    AtCiA = A.T @ Ci_A
    G = AtCiA - XtCiA.T @ np.linalg.solve(M, XtCiA)
    return aPy, 0.5 * (G + G.T), np.diag(AtCiA).copy()


def arc_length(G: FloatArray, keep: npt.NDArray[np.bool_]) -> float:
    """Σ arccos |cos| between neighbouring kept columns of the projected Gram G (module docstring)."""
    idx = np.flatnonzero(keep)
    total = 0.0
    for a, b in itertools.pairwise(idx):
        c = abs(G[a, b]) / math.sqrt(G[a, a] * G[b, b])
        total += math.acos(min(c, 1.0))
    return total


def resolve(
    ev: StaticEvidence,
    cand: Candidate,
    X: FloatArray,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
    alpha: float,
    notes: dict[str, str],
    th: Thresholds = THRESHOLDS,
) -> Candidate | None:
    """The family ``cand`` profiled into a fixed candidate at its best value, its ``tries`` from
    Davies' bound, or ``None`` (why goes to ``notes``): module docstring."""
    fam = cand.family
    assert fam is not None
    found = _profile(ev, fam, X, noise, K, fixed, th)
    if found is None:
        notes[cand.label] = (
            "cannot be told apart from the model's other terms on this recording at any τ searched"
        )
        return None
    v, lr_v, lr_null, length = found
    over_null = lr_v - lr_null
    nested = float(chi2.isf(th.false_alarm, 1))
    if over_null <= nested:
        if lr_v > davies_gate(alpha, length):
            notes[cand.label] = (
                f"its best time constant ({v:.3g} s) fits no better than none (likelihood ratio "
                f"{over_null:.1f} over τ = 0, gate {nested:.1f}): a plain {fam.reduces_to}, left to "
                "that candidate"
            )
        return None
    return _fixed(ev, fam, X, noise, K, fixed, v, th, effective_tries(alpha, length))


def reprofiled(
    ev: StaticEvidence,
    cands: list[Candidate],
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
    th: Thresholds = THRESHOLDS,
) -> list[Candidate]:
    """``cands`` with each candidate resolved from a family profiled again under ``noise`` (the
    final model's), the others in the design: its value and sigmas then belong to the noise the
    model is reported under (the selection profiled it under the noise of its step, whose slow
    wander still held the misfit the candidate explains). Admission is not judged again."""
    out = list(cands)
    for j, c in enumerate(cands):
        fam = c.resolved_from
        if fam is None:
            continue
        X = design(ev, K, [o for o in out if o is not out[j]])
        found = _profile(ev, fam, X, noise, K, fixed, th)
        if found is not None:
            out[j] = _fixed(ev, fam, X, noise, K, fixed, found[0], th, c.tries)
    return out


def _profile(
    ev: StaticEvidence,
    fam: Family,
    X: FloatArray,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
    th: Thresholds,
) -> tuple[float, float, float, float] | None:
    """(v̂, LR(v̂), LR(null), Davies' length L) of the family beyond X, or ``None`` when no
    column of the grid has leverage beyond X."""
    A = np.hstack([fam.column(ev, K, v) for v in fam.grid] + [fam.null_column(ev, K)])
    aPy, G, aCa = projected_gram(ev, X, A, noise, K, fixed)
    d = np.maximum(np.diag(G), 0.0)
    keep = np.sqrt(d / np.maximum(aCa, 1e-300)) >= th.relative_leverage_min
    lr = np.where(keep, aPy**2 / np.maximum(d, 1e-300), 0.0)
    n = len(fam.grid)
    if not np.any(keep[:n]):
        return None
    k = int(np.argmax(lr[:n]))
    v, lr_v = _refined(ev, fam, X, noise, K, fixed, k, lr[:n])
    return v, lr_v, float(lr[n]), arc_length(G[:n, :n], keep[:n])


def _fixed(
    ev: StaticEvidence,
    fam: Family,
    X: FloatArray,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
    v: float,
    th: Thresholds,
    tries: float,
) -> Candidate:
    """The fixed candidate at v̂ with the joint information's sigmas and the search's ``tries``."""
    inflation, v_per_coef = _joint(ev, fam, X, noise, K, fixed, v, th)
    return replace(fam.at(v, inflation, v_per_coef), tries=tries, resolved_from=fam)


def _refined(
    ev: StaticEvidence,
    fam: Family,
    X: FloatArray,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
    k: int,
    lr: FloatArray,
) -> tuple[float, float]:
    """The grid's best (v, LR), moved to the vertex of the parabola in ln v through it and its
    neighbours when that is interior and fits better."""
    v = fam.grid[k]
    if not 0 < k < len(fam.grid) - 1:
        return v, float(lr[k])
    x = np.log(fam.grid[k - 1 : k + 2])
    c2, c1, _ = np.polyfit(x, lr[k - 1 : k + 2], 2)
    if c2 >= 0:
        return v, float(lr[k])
    x_top = float(np.clip(-c1 / (2.0 * c2), x[0], x[2]))
    v_top = math.exp(x_top)
    aPy, G, _ = projected_gram(ev, X, fam.column(ev, K, v_top), noise, K, fixed)
    lr_top = float(aPy[0] ** 2 / max(G[0, 0], 1e-300))
    return (v_top, lr_top) if lr_top > lr[k] else (v, float(lr[k]))


def _joint(
    ev: StaticEvidence,
    fam: Family,
    X: FloatArray,
    noise: NoiseParams,
    K: FloatArray,
    fixed: FloatArray | None,
    v: float,
    th: Thresholds,
) -> tuple[float, float]:
    """(inflation, v_per_coef) of ``Family.at`` from the joint information of (c, v) at v."""
    h = (th.lag_grid_ratio - 1.0) / 10.0
    A = np.hstack([fam.column(ev, K, v), fam.column(ev, K, v * (1 + h)), fam.column(ev, K, v * (1 - h))])
    aPy, G, _ = projected_gram(ev, X, A, noise, K, fixed)
    c = float(aPy[0] / max(G[0, 0], 1e-300))
    D = np.array([[1.0, 0.0], [0.0, c / (2 * v * h)], [0.0, -c / (2 * v * h)]])
    info = D.T @ G @ D
    try:
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        return float("inf"), float("inf")
    g00 = float(G[0, 0])
    return float(max(cov[0, 0] * g00, 1.0)), float(math.sqrt(max(cov[1, 1], 0.0) * g00) * abs(c))
