"""Diagnosis: where a recording and the first-order model differ, which physics was left out.

``diagnose(evidence)`` runs the whole chain on a static recording's evidence (a moving-table
recording goes to :func:`bench.diagnosis.dynamic.diagnose_dynamic` instead):

1. observability of every catalogue effect on this recording (``effects``);
2. greedy forward selection with an F gate and BIC (``selection``), the
   noise taken from the recording (window scatter, plus slow noise estimated by REML):
   the catalogue first, then the term library beyond it (``library``), the pose error
   (a catch-all, ``catch_all``) last;
3. a catalogue effect a library term made redundant is dropped, and every structured
   effect must lower the leave-one-window-out prediction error of its channels (``_referee``);
4. refit with the chosen effects: parameters with sigmas, residuals before/after (``refit``);
5. where the first-order residuals are largest and what they correlate with
   (``residuals``, ``regressors``); whether the final model still fails the recording's
   noise (``unexplained``: χ² whole, per channel, channels against each other).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2 as chi2_dist
from scipy.stats import f as f_dist

from bench.diagnosis.catch_all import gls_channel_forms, satterthwaite_tails
from bench.diagnosis.effects import CATALOGUE, NEEDS_TABLE, Candidate, pose_response
from bench.diagnosis.effects.base import FloatArray, first_order_design
from bench.diagnosis.effects.settling import settling_duration, settling_test
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.library import EFFECT, LibraryTerm, library_terms, physics
from bench.diagnosis.library import candidate as library_candidate
from bench.diagnosis.likelihood import NoiseParams, covariance, gls, window_covariance, without_pose
from bench.diagnosis.refit import ModelFit, effect_parameters, model_sequence
from bench.diagnosis.regressors import correlations
from bench.diagnosis.residuals import CHANNELS, summarise, where
from bench.diagnosis.result import Diagnosis, Discovery, Finding, ModelSummary, Unexplained
from bench.diagnosis.selection import FALSE_ALARM, ModelState, design, fit_model, scale_matrix, select
from bench.diagnosis.summaries import summary

__all__ = ["Diagnosis", "StaticEvidence", "diagnose"]

CONFOUND_COSINE = 0.8
"""Two effects whose signatures (beyond the first-order model) have |cos| above this are
reported as indistinguishable on the recording."""


NO_TABLE_REASON = (
    "needs a table (its motion, encoders, base or ringing after a move); this recording has no table"
)


def _noise_text(noise: NoiseParams) -> str:
    tau = ", ".join(f"{np.sqrt(t):.2g}" for t in noise.tau2)
    corr = (
        "independent between windows"
        if noise.corr_time_s <= 0
        else f"correlation time {noise.corr_time_s:.0f} s"
    )
    return (
        "window means: batch-means covariance of each window's samples; slow noise between "
        f"windows (REML): sigma = [{tau}] channel units, {corr}"
    )


def _summary(model: ModelFit) -> ModelSummary:
    terms = ("bias", "scale_matrix", *model.effects)
    return ModelSummary(
        terms=terms,
        residual_rms=float(np.sqrt(np.mean(model.resid**2))),
        chi2_dof=float(model.chi2_dof),
        bic=float(model.bic),
        resid=model.resid,
        z=model.resid / model.sigma,
    )


def _confounded(
    ev: StaticEvidence, K: FloatArray, chosen: list[Candidate], pool: list[Candidate]
) -> dict[str, dict[str, float]]:
    X0 = first_order_design(ev.f_m_s2)
    Q, _ = np.linalg.qr(X0)

    def sig(c: Candidate) -> FloatArray:
        a = c.columns(ev, K)
        a = a - Q @ (Q.T @ a)
        n = np.linalg.norm(a, axis=0)
        return a / np.where(n > 0, n, 1.0)

    out: dict[str, dict[str, float]] = {}
    for c in chosen:
        sc = sig(c)
        for d in pool:
            if d.effect == c.effect or d in chosen:
                continue
            cos = float(np.max(np.abs(sc.T @ sig(d))))
            if cos > CONFOUND_COSINE:
                prev = out.setdefault(c.effect, {}).get(d.effect, 0.0)
                out[c.effect][d.effect] = max(prev, cos)
    return out


def _why(ev: StaticEvidence, a: str, b: str) -> str:
    if {a, b} == {"temperature_bias", "bias_drift"} and ev.temp_c is not None:
        r = float(np.corrcoef(ev.temp_c, ev.mid_s)[0, 1])
        return (
            f": the temperature follows time, r = {r:.2f} between the windows' temperature and time; "
            "vary the temperature independently of time to separate them"
        )
    return ""


UNEXPLAINED_ALPHA = 1e-3
"""Level of the final model's χ² tests (whole and per channel, two-sided, Bonferroni over 3)."""


def _prune_catalogue(
    ev: StaticEvidence,
    state: ModelState,
    pool: list[Candidate],
    fixed: FloatArray | None,
    false_alarm: float,
    notes: dict[str, str],
) -> list[str]:
    """Drop catalogue effects that entered before a library term and are not needed once it is in.

    Each catalogue effect of the model is removed in turn (weakest first) and its Wald
    statistic, under the model's noise, judged against the gate it passed to enter; one
    that fails it is dropped and the model refitted (a library term that mimics the
    catalogue never enters in the first place: it is tried after the catalogue).
    """
    assert state.noise is not None and state.fit is not None
    dropped: list[str] = []
    if not any(c.effect.startswith(EFFECT + ":") for c in state.candidates):
        return dropped
    n_cat = len(pool)
    while True:
        K = scale_matrix(state.fit)
        X = design(ev, K, state.candidates)
        C = covariance(ev.V, ev.mid_s, state.noise, pose_response(ev, K), fixed)
        z = ev.y.reshape(-1)
        full = gls(X, z, C).chi2
        weakest: tuple[float, str, float] | None = None
        for effect in dict.fromkeys(c.effect for c in state.candidates):
            if effect.startswith(EFFECT + ":"):
                continue
            keep = [c for c in state.candidates if c.effect != effect]
            q = sum(len(c.names) for c in state.candidates if c.effect == effect)
            lr = gls(design(ev, K, keep), z, C).chi2 - full
            gate = q * float(f_dist.ppf(1.0 - false_alarm / max(n_cat, 1), q, ev.n_obs - X.shape[1]))
            if lr < gate and (weakest is None or lr / gate < weakest[0]):
                weakest = (lr / gate, effect, lr)
        if weakest is None:
            return dropped
        _, effect, lr = weakest
        dropped.append(effect)
        state.candidates = [c for c in state.candidates if c.effect != effect]
        state.steps = [s for s in state.steps if s.effect != effect]
        terms = ", ".join(c.label for c in state.candidates if c.effect.startswith(EFFECT + ":"))
        notes[effect] = (
            f"entered before the library's {terms} and is not needed once it is in "
            f"(its statistic falls to {lr:.1f}, below its gate): dropped"
        )
        state.noise, state.fit, _ = fit_model(ev, state.candidates, state.pose, K, fixed, state.noise)


def loo_scores(ev: StaticEvidence, X: FloatArray, C: FloatArray) -> FloatArray:
    """(3,) leave-one-window-out prediction error per channel: Σ_w r_wi² / C_ww,ii with
    r_w = y_w − X_w θ̂₋w, θ̂₋w the GLS estimate without window w's three rows (C's submatrix)."""
    z = ev.y.reshape(-1)
    out = np.zeros(3)
    for w in range(ev.m):
        keep = np.ones(ev.n_obs, dtype=bool)
        keep[3 * w : 3 * w + 3] = False
        try:
            th = gls(X[keep], z[keep], C[np.ix_(keep, keep)]).theta
        except ValueError:
            return np.full(3, np.inf)
        r = z[3 * w : 3 * w + 3] - X[3 * w : 3 * w + 3] @ th
        out += r * r / np.diag(C)[3 * w : 3 * w + 3]
    return out


def _referee(ev: StaticEvidence, state: ModelState, fixed: FloatArray | None, notes: dict[str, str]) -> None:
    """Out-of-sample referee of the structured effects (catalogue and library).

    Each effect in the model must lower the leave-one-window-out prediction error
    (``loo_scores``) of the channels it acts on, under the model's noise; a term that only
    bends the fit towards the windows it was fitted to (a random pattern that a few columns
    happen to follow) predicts a left-out window no better than the model without it. The
    worst offender is dropped and the model refitted, until every effect earns its place.
    """
    while True:
        assert state.noise is not None and state.fit is not None
        K = scale_matrix(state.fit)
        effects = list(dict.fromkeys(c.effect for c in state.candidates))
        if not effects:
            return
        C = covariance(ev.V, ev.mid_s, state.noise, pose_response(ev, K), fixed)
        full = loo_scores(ev, design(ev, K, state.candidates), C)
        worst: tuple[float, str, float, float] | None = None
        for effect in effects:
            mine = [c for c in state.candidates if c.effect == effect]
            chans = sorted({i for c in mine for i in c.channels})
            keep = [c for c in state.candidates if c.effect != effect]
            without = loo_scores(ev, design(ev, K, keep), C)
            gain = float(np.sum(without[chans]) - np.sum(full[chans]))
            if gain <= 0 and (worst is None or gain < worst[0]):
                worst = (gain, effect, float(np.sum(without[chans])), float(np.sum(full[chans])))
        if worst is None:
            return
        gain, effect, before, after = worst
        state.candidates = [c for c in state.candidates if c.effect != effect]
        state.steps = [s for s in state.steps if s.effect != effect]
        notes[effect.removeprefix(EFFECT + ":")] = (
            "passed its gate but does not predict a left-out window better than the model without it "
            f"(leave-one-window-out chi2 {after:.1f} with it, {before:.1f} without): a pattern the "
            "windows happen to follow, not claimed"
        )
        state.noise, state.fit, _ = fit_model(ev, state.candidates, state.pose, K, fixed, state.noise)


def _discovery(
    ev: StaticEvidence,
    t: LibraryTerm,
    final: ModelFit,
    seq: list[ModelFit],
    k: int,
    K: FloatArray,
    state: ModelState,
    channel_unit: str,
    lib_terms: dict[str, LibraryTerm],
    pool: list[Candidate],
) -> Discovery:
    """The contract entry of one library term in the final model."""
    key = f"{EFFECT}:{t.label}"
    params, sigma = effect_parameters(final, key, K)
    X0 = first_order_design(ev.f_m_s2)
    Q, _ = np.linalg.qr(X0)
    mine = library_candidate(t).columns(ev, K)[:, 0]
    mine = mine - Q @ (Q.T @ mine)
    mine /= np.linalg.norm(mine)
    alike: list[tuple[float, str]] = []
    for other_key, other in lib_terms.items():
        if other_key == key or other.channel != t.channel:
            continue
        a = library_candidate(other).columns(ev, K)[:, 0]
        a = a - Q @ (Q.T @ a)
        cos = abs(float(mine @ a)) / max(float(np.linalg.norm(a)), 1e-300)
        if cos > CONFOUND_COSINE:
            alike.append((cos, other.term))
    for c in pool:
        if t.channel not in c.channels:
            continue
        a = c.columns(ev, K)
        a = a - Q @ (Q.T @ a)
        nrm = np.linalg.norm(a, axis=0)
        cos = float(np.max(np.abs(mine @ a) / np.maximum(nrm, 1e-300)))
        if cos > CONFOUND_COSINE:
            alike.append((cos, c.label))
    alike.sort(reverse=True)
    text = physics(t)
    if t.aliases:
        text += f"; on this pose set it is the same signature as {', '.join(t.aliases)}"
    if alike:
        text += "; it fits this recording about as well as " + ", ".join(
            f"{name} (|cos| = {cos:.2f})" for cos, name in alike[:4]
        )
    step = next(s for s in state.steps if s.effect == key)
    return Discovery(
        channel=CHANNELS[t.channel],
        term=t.term,
        coefficient=float(params["coefficient"]),  # type: ignore[arg-type]
        sigma=float(sigma["coefficient"]),  # type: ignore[arg-type]
        unit=f"{channel_unit or 'channel unit'} per {t.unit}",
        delta_bic=float(seq[k + 1].bic - seq[k].bic),
        residual_rms_after=float(np.sqrt(np.mean(seq[k + 1].resid ** 2))),
        physics=text,
        lr=float(step.lr),
        confounded_with=tuple(name for _, name in alike[:4]),
    )


def _unexplained(
    ev: StaticEvidence, final: ModelFit, state: ModelState, K: FloatArray, fixed: FloatArray | None
) -> Unexplained | None:
    """The final model's χ² tests against the recording's noise (``UNEXPLAINED_ALPHA``).

    Whole: χ² = rᵀ C⁻¹ r against χ²_{n−p}. Per channel: q_i (``catch_all.channel_forms``)
    against the scaled χ² c_i χ²_{ν_i} of its mean e_i and variance under the final noise
    model, two-sided, at ``UNEXPLAINED_ALPHA`` / 3 each. Channels against each other: the
    slow noise is one input-referred level, so (q_i/e_i)/(q_j/e_j) ~ F(ν_i, ν_j); the largest
    over the smallest, times 6 ordered pairs, at ``UNEXPLAINED_ALPHA`` (a channel far below
    what the shared level implies says that level was inflated by another channel's mismatch).
    """
    assert state.noise is not None
    noise = state.noise if final.pose else without_pose(state.noise)
    cov = window_covariance(ev.V, ev.mid_s, noise, pose_response(ev, K), fixed)
    X = design(ev, K, list(final.candidates))
    n, p = X.shape
    q, e, v = gls_channel_forms(cov, X, ev.y.reshape(-1))
    lo, up = satterthwaite_tails(q, e, v)
    p_ch = np.minimum(1.0, 2.0 * np.minimum(lo, up))
    p_all = float(chi2_dist.sf(final.fit.chi2, max(n - p, 1)))
    worst = int(np.argmin(p_ch))
    ratio = q / np.maximum(e, 1e-300)
    nu = 2.0 * e * e / np.maximum(v, 1e-300)
    hi, low = int(np.argmax(ratio)), int(np.argmin(ratio))
    p_pair = min(1.0, 6.0 * float(f_dist.sf(ratio[hi] / max(ratio[low], 1e-300), nu[hi], nu[low])))
    if p_all >= UNEXPLAINED_ALPHA and p_ch[worst] >= UNEXPLAINED_ALPHA / 3 and p_pair >= UNEXPLAINED_ALPHA:
        return None
    ch = int(np.argmax(ratio))
    z = final.resid[:, ch] / final.sigma[:, ch]
    w = int(np.argmax(np.abs(z)))
    others = [f"{CHANNELS[i]} {ratio[i]:.2f}" for i in range(3) if i != ch]
    where_text = (
        f"{CHANNELS[ch]}: chi2 {q[ch]:.1f} where the noise model expects {e[ch]:.1f} "
        f"(ratio {ratio[ch]:.2f}; {', '.join(others)}), strongest in window {ev.labels[w]} "
        f"(residual {z[w]:+.1f} sigma)"
    )
    corr = correlations(ev, final.resid, final.sigma)
    names: list[str] = []
    for c in corr:
        if c.significant and f"{c.regressor} on {CHANNELS[c.channel]}" not in names:
            names.append(f"{c.regressor} on {CHANNELS[c.channel]}")
    return Unexplained(
        chi2_dof=float(final.chi2_dof),
        test=(
            f"chi2 at {UNEXPLAINED_ALPHA:g} (whole model, p = {p_all:.2g}); per channel two-sided "
            f"at {UNEXPLAINED_ALPHA / 3:.2g} (worst {CHANNELS[worst]}, p = {p_ch[worst]:.2g}); channels "
            f"against each other, F of {CHANNELS[hi]} over {CHANNELS[low]} at {UNEXPLAINED_ALPHA:g} "
            f"(p = {p_pair:.2g})"
        ),
        p_value=float(min(p_all, 3.0 * p_ch[worst], p_pair)),
        where=where_text,
        correlates_with=tuple(names),
        channels={CHANNELS[i]: float(ratio[i]) for i in range(3)},
    )


def diagnose(
    ev: StaticEvidence,
    *,
    unit: str = "",
    channel_unit: str = "",
    source: str = "",
    false_alarm: float = FALSE_ALARM,
    free_orientation_rad: float = 0.1,
    use_library: bool = True,
) -> Diagnosis:
    """Diagnose a static recording (module docstring).

    :param ev: the recording's static evidence.
    :param false_alarm: false-alarm probability of one selection step (``selection.FALSE_ALARM``);
        the within-window settling test runs at a tenth of it.
    :param use_library: search the term library beyond the catalogue (``library``).
    :param free_orientation_rad: for ``orientation_known=False`` evidence (f taken from the
        data), the standard deviation given to each window's orientation about the two axes
        perpendicular to gravity, so that only the magnitude of each reading is evidence.
    :returns: :class:`~bench.diagnosis.result.Diagnosis`.
    :raises ValueError: fewer than 5 windows (10 orientation-free), or a pose set that cannot
        identify bias and K.
    """
    if ev.m < 5:
        raise ValueError(
            f"a diagnosis needs at least 5 static windows (first-order model + 1 dof), got {ev.m}"
        )
    if not ev.orientation_known and ev.m < 10:
        raise ValueError(
            "an orientation-free diagnosis needs at least 10 static windows (9 parameters from |f| = g "
            f"+ 1 dof: with fewer the fit passes through every window and nothing can be tested), got {ev.m}"
        )
    X0 = first_order_design(ev.f_m_s2)
    if np.linalg.matrix_rank(X0) < 12:
        raise ValueError("the windows' gravity directions lie on one plane: bias and K cannot be determined")
    unobservable: dict[str, str] = {}
    pool: list[Candidate] = []
    pose_ok = settle_ok = False
    for eff in CATALOGUE:
        ok, reason = eff.observable(ev)
        if eff.id in NEEDS_TABLE and not ev.has_table:
            ok, reason = False, NO_TABLE_REASON
        if not ok:
            unobservable[eff.id] = reason
        elif eff.kind == "columns":
            pool.extend(eff.candidates(ev))
        elif eff.kind == "variance":
            pose_ok = True
        elif eff.kind == "window":
            settle_ok = True
    fixed = None
    if not ev.orientation_known:
        K0 = np.asarray(np.linalg.lstsq(X0, ev.y.reshape(-1), rcond=None)[0][3:12], dtype=float).reshape(3, 3)
        J = pose_response(ev, K0)
        fixed = free_orientation_rad**2 * np.einsum("wik,wjk->wij", J, J)
    lib_terms: dict[str, LibraryTerm] = {}
    if ev.orientation_known and use_library:
        terms, _ = library_terms(ev)
        lib_terms = {f"{EFFECT}:{t.label}": t for t in terms}
    elif not ev.orientation_known:
        unobservable[EFFECT] = (
            "the library's terms need the specific force the recording says each window saw; an "
            "orientation-free diagnosis has only the magnitude of each reading"
        )
    state, notes = select(
        ev,
        pool,
        pose_allowed=pose_ok,
        fixed=fixed,
        false_alarm=false_alarm,
        library=[library_candidate(t) for t in lib_terms.values()],
        simplicity={t.label: t.degree for t in lib_terms.values()},
    )
    assert state.fit is not None and state.noise is not None
    dropped = _prune_catalogue(ev, state, pool, fixed, false_alarm, notes)
    if dropped:
        # the library's terms were chosen beside the dropped effects: choose them again without
        state, notes2 = select(
            ev,
            [c for c in pool if c.effect not in dropped],
            pose_allowed=pose_ok,
            fixed=fixed,
            false_alarm=false_alarm,
            library=[library_candidate(t) for t in lib_terms.values()],
            simplicity={t.label: t.degree for t in lib_terms.values()},
        )
        notes.update({k: v for k, v in notes2.items() if k not in notes})
    _referee(ev, state, fixed, notes)
    assert state.fit is not None and state.noise is not None
    K = scale_matrix(state.fit)
    order = list(dict.fromkeys(s.effect for s in state.steps))
    seq = model_sequence(ev, order, state.candidates, state.pose, state.noise, K, fixed)
    final = seq[-1]
    span = float(np.ptp(ev.mid_s))
    confounded = _confounded(ev, K, state.candidates, pool)
    findings = []
    discovered = []
    for k, effect in enumerate(order):
        if effect in lib_terms:
            discovered.append(
                _discovery(ev, lib_terms[effect], final, seq, k, K, state, channel_unit, lib_terms, pool)
            )
            continue
        if effect == "pose_error":
            assert final.pose_angles is not None and final.pose_sigma is not None
            params: dict[str, object] = {"angles_rad": final.pose_angles.tolist()}
            sigma: dict[str, object] = {"angles_rad": final.pose_sigma.tolist()}
        else:
            params, sigma = effect_parameters(final, effect, K)
        text = summary(effect, params, sigma, ev.labels, span)
        if effect == "pose_error":
            text += (
                f" ({state.pose_edf:.1f} effective degrees of freedom, charged in its BIC change, which is "
                "the conditional one given the angles; the scatter it implies is on every channel it moves)"
            )
            if ev.table_rad is not None:
                text += (
                    "; the table's encoders say where the table was, so this is a claim about the "
                    "fixture: the unit moved on its mount (loose clamp, shifting adapter)"
                )
        conf = confounded.get(effect, {})
        if conf:
            text += "; on this recording it cannot be told from " + ", ".join(
                f"{other} (signatures alike, |cos| = {cos:.2f}{_why(ev, effect, other)})"
                for other, cos in sorted(conf.items())
            )
        findings.append(
            Finding(
                effect=effect,
                summary=text,
                parameters=params,
                sigma=sigma,
                delta_bic=float(
                    seq[k + 1].bic - seq[k].bic
                    if effect != "pose_error"
                    else next(st.delta_bic for st in state.steps if st.effect == "pose_error")
                ),
                lr=float(sum(s.lr for s in state.steps if s.effect == effect)),
                residual_rms_after=float(np.sqrt(np.mean(seq[k + 1].resid ** 2))),
                explanation=next(e.explanation for e in CATALOGUE if e.id == effect),
                confounded_with=tuple(sorted(conf)),
            )
        )
    note_list = [f"{label}: {text}" for label, text in sorted(notes.items())]
    for f in findings:
        if f.confounded_with:
            note_list.append(
                f"{f.effect} fits this recording about as well as {', '.join(f.confounded_with)}: "
                "the recording cannot tell them apart (see the finding's summary)"
            )
    if settle_ok:
        assert ev.window_samples is not None and ev.sample_rate_hz is not None
        st = settling_test(ev.window_samples, ev.sample_rate_hz)
        if st.p_value < false_alarm / 10:
            params_s: dict[str, object] = {
                "frequency_hz": st.frequency_hz,
                "early_power_ratio": st.early_power_ratio,
            }
            sigma_s: dict[str, object] = {}
            try:
                dur, dur_sigma = settling_duration(ev.window_samples, ev.sample_rate_hz, st.frequency_hz)
                params_s["duration_s"], sigma_s["duration_s"] = dur, dur_sigma
            except ValueError as exc:
                note_list.append(str(exc))
            lr_s = float(st.statistic - st.dof)
            findings.append(
                Finding(
                    effect="settling",
                    summary=summary("settling", params_s, sigma_s, ev.labels, span),
                    parameters=params_s,
                    sigma=sigma_s,
                    delta_bic=float(-lr_s + 2.0 * np.log(st.n_obs)),
                    lr=lr_s,
                    residual_rms_after=float(np.sqrt(np.mean(final.resid**2))),
                    explanation=next(e.explanation for e in CATALOGUE if e.id == "settling"),
                )
            )
    base = _summary(seq[0])
    rs = summarise(ev, seq[0].resid, seq[0].sigma)
    unexplained = _unexplained(ev, final, state, K, fixed)
    return Diagnosis(
        unit=unit,
        channel_unit=channel_unit,
        method="static" if ev.orientation_known else "orientation-free",
        baseline=base,
        final=_summary(final),
        findings=tuple(findings),
        channel_ratio=rs.channel_ratio,
        where=where(ev, rs),
        correlations=tuple(correlations(ev, seq[0].resid, seq[0].sigma)),
        unobservable=unobservable,
        notes=(*note_list, _noise_text(state.noise)),
        noise_text=_noise_text(state.noise),
        labels=ev.labels,
        mid_s=ev.mid_s,
        bias=state.fit.theta[:3].copy(),
        K=K,
        source=source,
        discovered=tuple(discovered),
        unexplained=unexplained,
    )
