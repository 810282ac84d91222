"""Diagnosis of a moving-table recording (``rate-1axis``, ``oscillation-2axis``).

Baseline: raw = b + K f with f from the believed geometry (the sidecar's lever arm, level
table, no skew), fitted to every usable sample by the dynamic batch fit
(``bench.estimation.dynamic_batch``). Candidates: the dynamic model's terms
(``dynamic_model.TERM_ORDER``) that the motion determines (Fisher information of the
extended model of full rank, ``observability``). Greedy forward selection, as for static
windows: every candidate is fitted, its departure δ from the baseline value

    lever_arm: r − r_sidecar (3);  proof_mass_offsets: q_i − mean(q) (rank 6, only once
    the lever arm is in);  nonlinearity_quadratic: k2 (3);  table_tilt: (a, b);  time_skew: δ

is judged by a Wald statistic W = δᵀ Cov(δ)⁻¹ δ with the fit's sandwich covariance (it
carries the recording's own coloured noise: bias wander over the score blocks) against
χ²_q at false_alarm / N (N candidates in the step); it enters if W passes and its BIC
change, 3 n_used Σ_c ln(σ̂²_c,1 / σ̂²_c,0) / 3 + q ln(3 n_used), is negative.

``sensor_lowpass``: a first-order low-pass τ ẏ = x − y is, for ωτ ≪ 1, y ≈ x − τ ẋ, the
same signature as a delay of τ; at the procedures' rates (ωτ < 0.01) the two cannot be
told apart, so a delay found is reported as ``time_skew`` confounded with ``sensor_lowpass``.

After the catalogue, the moving term library (``library_motion``, searched by
``library_motion_search``, reported in ``discovered``); where a discovered term makes the
catalogue's later steps redundant, the catalogue path is cut back (``library_motion_swap``).
``claim_catalogue`` is that claim, shared with ``calibrate``'s term selection.

Residuals and correlates: 1 s block means of the baseline residuals (the "windows" of the
report) against ω² = −tr(B_sym)/2, |ω̇| (from the antisymmetric part of B), f_i², |f_i|, time
and temperature, by ``regressors.block_correlations``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.bench_families import moving_stage as bench_stage
from bench.diagnosis.dynamic_summary import block_summary, motion_regressors, unexplained_blocks
from bench.diagnosis.effects import CATALOGUE
from bench.diagnosis.greedy import Trial, best, forward, step_alpha
from bench.diagnosis.library_motion_search import (
    MotionLibraryResult,
    discovery,
    refit_terms,
    search_motion_library,
)
from bench.diagnosis.library_motion_swap import cut_catalogue, fit_bic
from bench.diagnosis.residuals import where_text
from bench.diagnosis.result import Diagnosis, Finding
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit, fit_dynamic_batch, linear_start, white_sigma
from bench.estimation.dynamic_model import TERM_ORDER, ModelSpec, initial_theta
from bench.estimation.motion_data import MotionData
from bench.estimation.observability import fisher_information, information_report

FloatArray = np.ndarray
CHANNELS = ("ax", "ay", "az")
PARAM = {
    "lever_arm": ("r_m", "m"),
    "proof_mass_offsets": ("rho_m", "m"),
    "nonlinearity_quadratic": ("k2_per_g", "1/g"),
    "table_tilt": ("tilt_rad", "rad"),
    "time_skew": ("delay_s", "s"),
}
STATIC_ONLY = {
    "scale_asymmetry": "not a term of the dynamic model; |f_i| is shown among the residual's correlates "
    "(after bias and K), not fitted: tested on static windows",
    "cross_coupling": "f_j·f_k terms are not in the dynamic model (K's off-diagonal is the linear part): "
    "tested on static windows",
    "temperature_bias": "over one moving run the temperature changes little and, on a warm-up, follows time: "
    "as bias_drift, it cannot be told from the bias wander's own trend here",
    "bias_drift": "a linear drift over one run cannot be told from the bias wander's own trend: nothing in a "
    "moving recording measures the wander at the run's length (no still windows), and the batch fit's "
    "covariance sees the noise only at its score-block scale; time is shown among the correlates",
    "pose_error": "a moving recording has no per-window poses",
    "encoder_offset": "not a term of the dynamic model: an outer-axis offset is a turn about the rotation "
    "axis that K absorbs; a middle- or inner-axis offset tilts gravity and needs static windows",
    "settling": "tested on static windows only (needs still windows after each stop)",
}


def _delta(fit: DynamicFit, term: str, lever: FloatArray) -> tuple[FloatArray, FloatArray, int]:
    """(δ, Cov δ, dof) of the module docstring.

    Once the proof masses are in, the lever arm is their mean position r = (q_x + q_y + q_z)/3.
    """
    if term == "lever_arm" and "lever_arm" not in fit.spec.terms:
        s = fit.spec.index("proof_mass_offsets")
        A = np.tile(np.eye(3) / 3.0, (1, 3))
        return A @ fit.theta[s] - lever, A @ fit.cov[s, s] @ A.T, 3
    s = fit.spec.index(term)
    th, C = fit.theta[s], fit.cov[s, s]
    if term == "lever_arm":
        return th - lever, C, 3
    if term == "proof_mass_offsets":
        T = np.eye(9) - np.tile(np.tile(np.eye(3) / 3.0, (1, 3)), (3, 1))
        return T @ th, T @ C @ T.T, 6
    return th, C, th.size


def _wald(d: FloatArray, C: FloatArray, q: int) -> float:
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    keep = np.argsort(w)[::-1][:q]
    u = V[:, keep].T @ d
    return float(np.sum(u * u / np.maximum(w[keep], 1e-300)))


def _loglik_term(fit: DynamicFit) -> float:
    return float(fit.n_used * np.sum(np.log(fit.noise_sigma**2)))


def _params(fit: DynamicFit, term: str, lever: FloatArray) -> tuple[dict[str, object], dict[str, object]]:
    name = PARAM[term][0]
    d, C, _ = _delta(fit, term, lever)
    sig = np.sqrt(np.clip(np.diag(C), 0.0, None))
    if term == "lever_arm":
        return {name: (d + lever).tolist()}, {name: sig.tolist()}
    if term == "proof_mass_offsets":
        return {name: d.reshape(3, 3).tolist()}, {name: sig.reshape(3, 3).tolist()}
    if term == "time_skew":
        return {name: float(d[0])}, {name: float(sig[0])}
    return {name: d.tolist()}, {name: sig.tolist()}


def _summary_text(term: str, p: dict[str, object], s: dict[str, object]) -> str:
    name, unit = PARAM[term]
    v, e = np.atleast_1d(np.asarray(p[name], dtype=float)), np.atleast_1d(np.asarray(s[name], dtype=float))
    k = int(np.argmax(np.abs(v) / np.maximum(e, 1e-300)))
    return f"{term}: {name} = {v.ravel()[k]:.3g} ± {e.ravel()[k]:.2g} {unit} (largest of {v.size} in sigmas)"


@dataclass(frozen=True)
class TermSelection:
    """The greedy forward selection of the dynamic model's terms (module docstring).

    :param candidates: terms the motion determines, tried in turn.
    :param unobservable: term -> why the motion cannot determine it.
    :param steps: (term, ΔBIC, Wald W) of each term admitted, in order.
    :param fits: the baseline fit, then the fit after each step (``fits[-1]`` is the final model).
    :param rejected: term -> why it did not enter (its statistics at the last step).
    :param false_alarm: false-alarm probability of one step.
    """

    candidates: tuple[str, ...]
    unobservable: dict[str, str]
    steps: tuple[tuple[str, float, float], ...]
    fits: tuple[DynamicFit, ...]
    rejected: dict[str, str]
    false_alarm: float

    @property
    def chosen(self) -> tuple[str, ...]:
        """The admitted terms, in order."""
        return tuple(t for t, _, _ in self.steps)


def _warm_start(fit: DynamicFit, spec: ModelSpec, lever: FloatArray) -> FloatArray:
    """Start of an extended model at the current fit: its parameters kept, the new term at
    the believed geometry (the proof masses at the fitted lever arm)."""
    th = fit.theta
    r = th[fit.spec.index("lever_arm")] if "lever_arm" in fit.spec.terms else lever
    out = initial_theta(spec, th[:3], th[3:12].reshape(3, 3), r)
    for t in fit.spec.terms:
        if t in spec.terms:
            out[spec.index(t)] = th[fit.spec.index(t)]
    return out


def select_terms(
    m: MotionData, y: FloatArray, g_m_s2: float, lever: FloatArray, *, th: Thresholds = THRESHOLDS
) -> TermSelection:
    """Greedy forward selection of the terms the recording supports (module docstring).

    :param m: the motion; :param y: (n, 3) raw samples; :param lever: (3,) believed lever arm (m).
    :raises ValueError: a motion that cannot determine bias and K.
    """
    sig_w = np.maximum(white_sigma(y[m.valid]), 1e-12)
    b0, K0 = linear_start(m, y, g_m_s2, lever)
    unobservable: dict[str, str] = {}
    pool = []
    for t in TERM_ORDER:
        spec = ModelSpec(("lever_arm", t)) if t == "proof_mass_offsets" else ModelSpec((t,))
        rep = information_report(
            fisher_information(m, initial_theta(spec, b0, K0, lever), spec, g_m_s2, lever, sig_w), spec.names
        )
        if rep.ok:
            pool.append(t)
        else:
            unobservable[t] = "not determined by this motion: " + "; ".join(rep.unobservable)
    n_obs = 3 * int(m.valid.sum())
    fits = [fit_dynamic_batch(m, y, g_m_s2, lever, ModelSpec(()))]
    chosen: list[str] = []
    steps: list[tuple[str, float, float]] = []
    rejected: dict[str, str] = {}

    def catalogue(n_steps: int) -> int | None:
        tried = [t for t in pool if t not in chosen and (t != "proof_mass_offsets" or "lever_arm" in chosen)]
        if not tried:
            return None
        alpha = step_alpha(th.false_alarm, len(tried))
        trials: list[Trial[tuple[str, DynamicFit]]] = []
        rejected.clear()
        for t in tried:
            spec1 = ModelSpec((*chosen, t))
            try:
                f1 = fit_dynamic_batch(m, y, g_m_s2, lever, spec1, theta0=_warm_start(fits[-1], spec1, lever))
            except ValueError as exc:
                rejected[t] = f"the fit with it failed: {exc}"
                continue
            d, C, q = _delta(f1, t, lever)
            w = _wald(d, C, q)
            crit = float(chi2_dist.ppf(1.0 - alpha, q))
            dbic = _loglik_term(f1) - _loglik_term(fits[-1]) + q * math.log(n_obs)
            trials.append(Trial((t, f1), w, crit, dbic))
            rejected[t] = (
                f"no evidence on this recording: Wald W = {w:.3g} against {crit:.3g} (chi2_{q} at "
                f"{alpha:.2g}), delta BIC {dbic:+.3g}"
            )
        win = best(trials)
        if win is None:
            return None
        t, f1 = win.item
        chosen.append(t)
        steps.append((t, win.delta_bic, win.statistic))
        fits.append(f1)
        rejected.pop(t, None)
        return n_steps + 1

    forward(0, [catalogue], len(pool))
    for t in pool:
        if t not in chosen and t not in rejected:
            rejected[t] = "tried only with lever_arm in the model (its offsets are relative to it)"
    return TermSelection(
        candidates=tuple(pool),
        unobservable=unobservable,
        steps=tuple(steps),
        fits=tuple(fits),
        rejected=rejected,
        false_alarm=th.false_alarm,
    )


@dataclass(frozen=True)
class CatalogueClaim:
    """The catalogue terms a moving recording's diagnosis claims, shared with ``calibrate``.

    :param selection: the greedy catalogue selection (``select_terms``).
    :param k: how many of its steps are claimed: the first k (the later ones replaced by
        library terms that explain the recording better without them, ``cut_catalogue``).
    :param library: the library search after those k steps; :param values: its base values.
    :param note: why steps were replaced, or ``None``.
    """

    selection: TermSelection
    k: int
    library: MotionLibraryResult
    values: dict[str, FloatArray]
    note: str | None

    @property
    def terms(self) -> tuple[str, ...]:
        """The claimed catalogue terms, in order."""
        return self.selection.chosen[: self.k]

    @property
    def fit(self) -> DynamicFit:
        """The catalogue model of the claimed terms."""
        return self.selection.fits[self.k]


def claim_catalogue(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever: FloatArray,
    temp_c: FloatArray | None,
    *,
    library: bool = True,
    th: Thresholds = THRESHOLDS,
) -> CatalogueClaim:
    """The catalogue terms the recording supports and the diagnosis claims: the greedy selection,
    then the steps a library path explains better replaced (``cut_catalogue``). ``library``
    False: no library search, every selected step claimed. ``calibrate`` fits these terms, so it
    never fits a term the diagnosis would not claim.
    """
    sel = select_terms(m, y, g_m_s2, lever, th=th)
    if not library:
        return CatalogueClaim(sel, len(sel.steps), MotionLibraryResult((), sel.fits[-1:], 0, ()), {}, None)

    def search(k: int) -> tuple[MotionLibraryResult, dict[str, FloatArray]]:
        span = _catalogue_span(sel, lever, k)
        return search_motion_library(m, y, g_m_s2, lever, sel.fits[k], temp_c, span, th=th)

    def rescore(k: int, full: MotionLibraryResult, vals: dict[str, FloatArray]) -> float:
        coef = np.array([i.coefficient for i in full.included])
        terms = [i.term for i in full.included]
        return fit_bic(refit_terms(m, y, g_m_s2, lever, sel.fits[k], terms, coef, vals, th)[0], len(terms))

    k, lib, vals, note = cut_catalogue(search, rescore, len(sel.steps), sel.chosen, th)
    return CatalogueClaim(sel, k, lib, vals, note)


def diagnose_dynamic(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever_arm_m: FloatArray,
    *,
    temp_c: FloatArray | None = None,
    unit: str = "",
    channel_unit: str = "",
    source: str = "",
    library: bool = True,
    thresholds: Thresholds = THRESHOLDS,
    head_to_head: bool = True,
) -> Diagnosis:
    """Diagnose a moving-table recording (module docstring).

    :param m: the motion (``motion_data.prepare_motion``); :param y: (n, 3) raw samples.
    :param lever_arm_m: (3,) the lever arm the recording believes (m).
    :param temp_c: (n,) temperature (°C) or ``None``.
    :param library: search the moving library after the catalogue (``library_motion``).
    :param head_to_head: a bench family found beside catalogue claims is weighed against them
        by running the diagnosis again without it (``family_referee``).
    :param thresholds: the diagnosis's knobs (``thresholds``).
    :raises ValueError: a motion that cannot determine bias and K.
    """
    lever = np.asarray(lever_arm_m, dtype=float).reshape(3)
    sig_w = np.maximum(white_sigma(y[m.valid]), 1e-12)
    th = thresholds
    claim = claim_catalogue(m, y, g_m_s2, lever, temp_c, library=library, th=th)
    sel, k_cut, lib, vals, cut_note = claim.selection, claim.k, claim.library, claim.values, claim.note
    unobservable = {**STATIC_ONLY, **sel.unobservable}
    n_obs = 3 * int(m.valid.sum())
    fits = [*sel.fits[: k_cut + 1], *lib.fits[1:]]
    steps = list(sel.steps[:k_cut])
    final = fits[-1]
    findings = []
    for k, (t, dbic, w) in enumerate(steps):
        p, s = _params(final, t, lever)
        conf = ("sensor_lowpass",) if t == "time_skew" else ()
        text = _summary_text(t, p, s)
        if conf:
            text += (
                "; a first-order sensor low-pass of that time constant gives the same signature at these "
                "rates (ωτ ≪ 1), so it cannot be told from sensor_lowpass"
            )
        findings.append(
            Finding(
                effect=t,
                summary=text,
                parameters=p,
                sigma=s,
                delta_bic=float(dbic),
                lr=float(w),
                residual_rms_after=float(fits[k + 1].residual_rms),
                explanation=next(e.explanation for e in CATALOGUE if e.id == t),
                confounded_with=conf,
            )
        )
    discovered = tuple(discovery(inc, final, channel_unit) for inc in lib.included)
    bench_found, alternative = bench_stage(
        m, y, g_m_s2, lever, final, lib.adjustment(vals) if lib.included else None, channel_unit, th,
        baseline=sel.fits[0], n_claims=len(steps) + len(lib.included), n_library=len(lib.included),
        rerun=None if not head_to_head else lambda y2: diagnose_dynamic(
            m, y2, g_m_s2, lever_arm_m, temp_c=temp_c, unit=unit, channel_unit=channel_unit, source=source,
            library=library, thresholds=th, head_to_head=False,
        ),
    )  # fmt: skip
    if alternative is not None:
        return alternative
    findings += bench_found
    regs = motion_regressors(m, y, final, g_m_s2, lever, temp_c)
    bs = block_summary(
        m, y, fits, g_m_s2, lever, sig_w, regs, n_obs,
        library=lib.adjustment(vals) if lib.included else None,
        library_terms=tuple(i.term.label for i in lib.included), th=th,
    )  # fmt: skip
    notes = (
        "sensor_lowpass: a low-pass of time constant τ looks like a delay of τ at these rates; "
        "a delay found is reported as time_skew",
        f"noise: white sigma from the samples' second differences [{', '.join(f'{v:.3g}' for v in sig_w)}] "
        "channel units; parameter sigmas from the batch fit's sandwich covariance (coloured noise included)",
        *lib.notes,
        *((cut_note,) if cut_note else ()),
    )
    unexplained = unexplained_blocks(bs, th)
    limit = f"{th.where_z:g} sigma in a {th.block_s:g} s block mean"
    return Diagnosis(
        unit=unit,
        channel_unit=channel_unit,
        method="dynamic",
        baseline=bs.baseline,
        final=bs.final,
        findings=tuple(findings),
        channel_ratio=bs.channel_ratio,
        where=where_text(bs.where, bs.where_beyond, bool(findings or discovered or unexplained), limit),
        correlations=bs.correlations,
        unobservable=unobservable,
        notes=notes,
        noise_text=notes[1],
        labels=bs.labels,
        mid_s=bs.mid_s,
        bias=final.theta[:3].copy(),
        K=final.theta[3:12].reshape(3, 3).copy(),
        source=source,
        discovered=discovered,
        unexplained=unexplained,
    )


def _catalogue_span(sel: TermSelection, lever: FloatArray, k: int) -> tuple[ModelSpec, FloatArray] | None:
    """The catalogue's observable terms together at the fit after its first k steps (the others at
    their null): a library term inside their span beyond the model is the catalogue's
    (``library_motion``)."""
    final = sel.fits[k]
    kept = sel.chosen[:k]
    spec = ModelSpec((*kept, *(t for t in sel.candidates if t not in kept)))
    if spec.terms == final.spec.terms:
        return None
    return spec, _warm_start(final, spec, lever)
