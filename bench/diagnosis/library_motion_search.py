"""Search of the moving library (``library_motion``) after the catalogue, with the recording's own noise.

Model with library terms: raw = h(θ; motion) + Σ_k c_k x_k e_{i_k} (``dynamic_model``; x_k a
monomial on channel i_k). Each step scores every candidate (``library_motion_scores``: the
statistic T with a Newey-West variance over the dynamic fit's blocks) and admits the best
one that passes F(1, ν) at α = ``library_share`` · ``false_alarm`` / N_L (``Thresholds``; N_L terms in the
library on this recording, ν the blocks' Satterthwaite degrees of freedom) and whose BIC
change, n Σ_c ln(σ̂²_c,1/σ̂²_c,0) + ln(3n) with the model refitted, is negative (as the
catalogue's). Among terms on the same channel whose signatures beyond the model are alike
(|cos| > ``alike_cosine``) and whose T lies within ``tie_chi2`` of the best, the simplest
(lowest degree) enters; the others are reported as confounded with it (``_choose``).

Before a term is a candidate: relative leverage beyond the model ≥ ``Thresholds.relative_leverage_min``
(else the motion does not determine it); not the catalogue's (its signature beyond the model
within |cos| ``Thresholds.alike_cosine`` of the span of the catalogue terms not in the model: those are
the catalogue's to claim, with its gates: the lever arm's ω²·r and ω̇·r, the proof masses,
the common skew K·ḟ, the tilt); not mostly a slow trend (more than ``Thresholds.slow_share`` of its
signature's energy beyond the model in the span of the cubic polynomials in t and in temp on
each channel: a bias wander makes those, and abs(f_z)·t, whose mean is a drift, took a bias
step otherwise); not an alias of a simpler term (|cos| > 1 − ``Thresholds.alias_tol``).

Refit: Gauss-Newton steps of the joint model (catalogue parameters and library coefficients)
until the library step is below a thousandth of its sigma, then the dynamic fit of
y − Σ c_k x_k e_{i_k} started there; the catalogue parameters' sigmas stay that fit's. A term's
reported sigma is its score's against the final model with the other terms in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import f as f_dist

from bench.diagnosis.library_motion import (
    CHANNELS,
    MotionTerm,
    base_values,
    candidate_terms,
    motion_bases,
    motion_physics,
)
from bench.diagnosis.library_motion_scores import (
    Stats,
    design,
    lib_columns,
    satterthwaite_dof,
    scores,
    solve_scaled,
)
from bench.diagnosis.result import Discovery
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit, fit_dynamic_batch
from bench.estimation.dynamic_model import ModelSpec, predict
from bench.estimation.motion_data import MotionData

FloatArray = np.ndarray


@dataclass(frozen=True)
class Included:
    """A library term in the model: the term, its coefficient and one sigma (channel units per
    unit of the term), its statistic T, BIC change and the residual RMS once it entered."""

    term: MotionTerm
    coefficient: float
    sigma: float
    lr: float
    delta_bic: float
    residual_rms_after: float
    alike: tuple[str, ...] = ()


@dataclass(frozen=True)
class MotionLibraryResult:
    """What the search found: the terms in order, the final fit (catalogue part), the fit of
    each step (``fits[0]`` the catalogue's), the library's size and why terms were left out."""

    included: tuple[Included, ...]
    fits: tuple[DynamicFit, ...]
    n_terms: int
    notes: tuple[str, ...]

    def adjustment(self, vals: dict[str, FloatArray]) -> FloatArray:
        """(n, 3) Σ c_k x_k e_{i_k} of the included terms."""
        n = vals["t"].shape[0]
        out = np.zeros((n, 3))
        for inc in self.included:
            out[:, inc.term.channel] += inc.coefficient * base_values(vals, inc.term.factors, slice(None))
        return out


def _loglik(fit: DynamicFit) -> float:
    return float(fit.n_used * np.sum(np.log(fit.noise_sigma**2)))


def refit_terms(
    m: MotionData,
    y: FloatArray,
    g: float,
    lever: FloatArray,
    fit: DynamicFit,
    terms: list[MotionTerm],
    coef: FloatArray,
    vals: dict[str, FloatArray],
    th: Thresholds = THRESHOLDS,
) -> tuple[DynamicFit, FloatArray]:
    """The catalogue model and the library coefficients fitted together (module docstring):
    Gauss-Newton steps of the joint model, [JᵀWJ JᵀWA; AᵀWJ AᵀWA] [δθ; δc] = [JᵀWe; AᵀWe], from
    the catalogue fit, until the library step is below 1e-3 of its sigma, then the dynamic fit
    of y − Σ c_k x_k started there (for its own covariance)."""
    coef = np.array(coef, dtype=float)
    theta = np.array(fit.theta, dtype=float)
    idx = np.flatnonzero(m.valid)
    cols = lib_columns(terms, vals, np.arange(m.n))
    w = 1.0 / fit.noise_sigma**2
    p, k = fit.spec.n_params, len(terms)
    chunk = th.motion_chunk_samples
    for _ in range(th.motion_refit_iter):
        y_adj = y - np.einsum("nck,k->nc", cols, coef)
        N, rhs = np.zeros((p + k, p + k)), np.zeros(p + k)
        for a in range(0, idx.size, chunk):
            sel = idx[a : a + chunk]
            raw, J = predict(
                theta, m.take(sel, rates=fit.spec.needs_rates), fit.spec, g, lever, jacobian=True
            )
            assert J is not None
            JA = np.concatenate([J, cols[sel]], axis=2)
            e = y_adj[sel] - raw
            for c in range(3):
                N += w[c] * JA[:, c, :].T @ JA[:, c, :]
                rhs += w[c] * JA[:, c, :].T @ e[:, c]
        step = solve_scaled(N, rhs[:, None])[:, 0]
        theta, coef = theta + step[:p], coef + step[p:]
        sig = np.sqrt(np.maximum(np.diag(solve_scaled(N, np.eye(p + k)))[p:], 1e-300))
        if np.all(np.abs(step[p:]) < 1e-3 * sig):
            break
    y_adj = y - np.einsum("nck,k->nc", cols, coef)
    return fit_dynamic_batch(m, y_adj, g, lever, fit.spec, theta0=theta), coef


def _screen(
    st: Stats, terms: list[MotionTerm], mono_index: dict[str, int], taken: set[str], th: Thresholds
) -> tuple[
    list[tuple[MotionTerm, int]], dict[str, list[str]], int, int, int
]:  # fmt: skip
    """Candidates of this step: (term, monomial index), aliases, and how many were not
    determined, the catalogue's, mostly a slow trend."""
    kept: list[tuple[MotionTerm, int]] = []
    aliases: dict[str, list[str]] = {}
    dropped = catalogue = slow = 0
    for c in range(3):
        eligible: list[tuple[MotionTerm, int]] = []
        for t in terms:
            if t.channel != c or t.label in taken:
                continue
            a = mono_index[t.term]
            if not np.isfinite(st.lev[c][a]) or st.lev[c][a] < th.relative_leverage_min:
                dropped += 1
            elif st.cat_cos2[c][a] > th.alike_cosine**2:
                catalogue += 1
            elif st.slow_cos2[c][a] > th.slow_share:
                slow += 1
            else:
                eligible.append((t, a))
        if not eligible:
            continue
        ix = np.array([a for _, a in eligible])
        Pc = st.P[c][np.ix_(ix, ix)]
        d = np.sqrt(np.maximum(np.diag(Pc), 1e-300))
        twin = np.tril(np.abs(Pc) / np.outer(d, d) > 1.0 - th.alias_tol, -1)
        is_kept = np.ones(ix.size, dtype=bool)
        for r in np.flatnonzero(twin.any(axis=1)):
            first = np.flatnonzero(twin[r, :r] & is_kept[:r])
            if first.size:
                is_kept[r] = False
                aliases.setdefault(eligible[first[0]][0].label, []).append(eligible[r][0].term)
        kept.extend(e for e, k in zip(eligible, is_kept, strict=True) if k)
    return kept, aliases, dropped, catalogue, slow


def _choose(
    st: Stats, pool: list[tuple[MotionTerm, int]], crit: float, th: Thresholds
) -> tuple[MotionTerm, int, float, tuple[str, ...]] | None:
    """The term to enter, its T and its alike rivals, or ``None`` (module docstring).

    Passing is judged on T (the serially correlated noise); the choice among the passing on
    the fit each term gives, G = U² / ãᵀWã (its Δχ² under the residual's own level: each
    term's T divides by its own variance estimate, which scatters by ~1/√ν between alike
    terms and would pick the luckiest of them). Terms alike the best (same channel, |cos| >
    ``th.alike_cosine``) within ``th.tie_chi2`` of its G, in units of the best's T (G·T/G), are a
    tie, which the simplest wins.
    """
    rows = []
    for t, a in pool:
        u, v, w = float(st.U[t.channel][a]), float(st.V[t.channel][a]), float(st.P[t.channel][a, a])
        if u * u / v > crit:
            rows.append((u * u / w, u * u / v, t, a))
    if not rows:
        return None
    top_G, top_T, top, ta = max(rows, key=lambda r: r[0])
    Pc = st.P[top.channel]
    tie = th.tie_chi2 * top_G / top_T

    def cos(b: int) -> float:
        return float(abs(Pc[ta, b])) / math.sqrt(max(float(Pc[ta, ta] * Pc[b, b]), 1e-300))

    alike = [
        r for r in rows if r[2].channel == top.channel and r[0] >= top_G - tie and cos(r[3]) > th.alike_cosine
    ]
    _, Tb, best, ba = min(alike, key=lambda r: (r[2].degree, -r[0]))
    return best, ba, Tb, tuple(r[2].term for r in alike if r[2] is not best)


def search_motion_library(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever: FloatArray,
    fit: DynamicFit,
    temp_c: FloatArray | None,
    catalogue: tuple[ModelSpec, FloatArray] | None,
    *,
    th: Thresholds = THRESHOLDS,
) -> tuple[MotionLibraryResult, dict[str, FloatArray]]:
    """Greedy search of the moving library after the catalogue (module docstring).

    :param m: the motion; :param y: (n, 3) raw samples; :param lever: (3,) believed lever arm (m).
    :param fit: the catalogue's final model.
    :param catalogue: (spec, θ) of the catalogue's observable terms together at the fit's values
        (the others at their null), whose span marks a term as the catalogue's; ``None``: none left.
    :returns: the result and the base quantities' values per sample (name -> (n,)).
    """
    bases, vals = motion_bases(m, fit, g_m_s2, lever, temp_c, th)
    terms = candidate_terms(bases, th)
    monos = list({t.term: t.factors for t in terms}.values())
    mono_index = {t.term: k for k, t in enumerate({t.term: t for t in terms}.values())}
    des, base = design(m, monos, vals, th)
    fits = [fit]
    included: list[Included] = []
    coef = np.zeros(0)
    notes: list[str] = []
    n_terms = 0
    first: Stats | None = None
    for _ in range(th.max_steps):
        inc_terms = [i.term for i in included]
        y_adj = y - np.einsum("nck,k->nc", lib_columns(inc_terms, vals, np.arange(m.n)), coef)
        st = scores(
            m,
            y_adj,
            fits[-1],
            g_m_s2,
            lever,
            inc_terms,
            des,
            base,
            vals,
            catalogue,
            shares=first is None,
            th=th,
        )
        if first is None:
            first = st
        else:  # the shares of the first step: the spans they measure do not move with a term
            st = replace(st, cat_cos2=first.cat_cos2, slow_cos2=first.slow_cos2)
        pool, aliases, dropped, cat, slow = _screen(st, terms, mono_index, {t.label for t in inc_terms}, th)
        if not included:
            n_terms = len(pool)
            notes.append(
                f"moving library: {len(pool)} terms on this recording ({len(terms)} monomial-channel pairs; "
                f"{dropped} not determined by this motion, {cat} the catalogue's own signature, {slow} "
                "mostly a slow trend a bias wander makes (powers of t, temp), "
                f"{sum(len(v) for v in aliases.values())} aliases of simpler terms); gate F(1, "
                f"{satterthwaite_dof(st.n_blocks):.1f}) at "
                f"{th.library_share * th.false_alarm / max(len(pool), 1):.2g}"
            )
        if not pool:
            break
        alpha = th.library_share * th.false_alarm / len(pool)
        crit = float(f_dist.ppf(1.0 - alpha, 1, satterthwaite_dof(st.n_blocks)))
        pick = _choose(st, pool, crit, th)
        if pick is None:
            break
        term, a, T, alike = pick
        term = replace(term, aliases=tuple(aliases.get(term.label, ())))
        c0 = float(st.U[term.channel][a] / st.P[term.channel][a, a]) / st.scale[a]
        new_fit, new_coef = refit_terms(
            m, y, g_m_s2, lever, fits[-1], [*inc_terms, term], np.append(coef, c0), vals, th
        )
        dbic = _loglik(new_fit) - _loglik(fits[-1]) + math.log(3 * new_fit.n_used)
        if dbic >= 0:
            notes.append(
                f"{term.label}: passes its gate (T = {T:.1f}) but its BIC change is {dbic:+.1f}: not added"
            )
            break
        included.append(Included(term, 0.0, 0.0, T, dbic, new_fit.residual_rms, alike))
        fits.append(new_fit)
        coef = new_coef
    # final coefficients and sigmas: each term against the model and the other terms
    final: list[Included] = []
    inc_all = [i.term for i in included]
    for k, inc in enumerate(included):
        # the residual of the final model (every term in), the term tested beyond the model and the others
        others = [i.term for j, i in enumerate(included) if j != k]
        y_adj = y - np.einsum("nck,k->nc", lib_columns(inc_all, vals, np.arange(m.n)), coef)
        one, one_base = design(m, [inc.term.factors], vals, th)
        st = scores(m, y_adj, fits[-1], g_m_s2, lever, others, one, one_base, vals, None, shares=False, th=th)
        c = inc.term.channel
        Pcc = float(st.P[c][0, 0])
        sig = math.sqrt(float(st.V[c][0])) / Pcc / float(st.scale[0])
        final.append(replace(inc, coefficient=float(coef[k]), sigma=sig))
    return MotionLibraryResult(tuple(final), tuple(fits), n_terms, tuple(notes)), vals


def discovery(inc: Included, final: DynamicFit, channel_unit: str) -> Discovery:
    """The ``discovered`` entry of an included term; K of the final model for its physics."""
    t = inc.term
    K = final.theta[3:12].reshape(3, 3)
    return Discovery(
        channel=CHANNELS[t.channel],
        term=t.term,
        coefficient=inc.coefficient,
        sigma=inc.sigma,
        unit=f"{channel_unit or 'channel unit'} per {t.unit}",
        delta_bic=inc.delta_bic,
        residual_rms_after=inc.residual_rms_after,
        physics=motion_physics(t, inc.coefficient, K),
        lr=inc.lr,
        confounded_with=tuple(dict.fromkeys((*t.aliases, *inc.alike))),
    )
