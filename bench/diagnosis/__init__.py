"""Diagnosis: where a recording and the first-order model differ, which physics was left out.

``diagnose(evidence)`` runs the whole chain on a static recording's evidence (a moving-table
recording goes to :func:`bench.diagnosis.dynamic.diagnose_dynamic` instead):

1. observability of every catalogue effect on this recording (``effects``);
2. greedy forward selection with an F gate and BIC (``selection``), the
   noise taken from the recording (window scatter, plus slow noise estimated by REML):
   the catalogue first, then the term library beyond it (``library``), the pose error
   (a catch-all, ``catch_all``) last;
3. a catalogue effect a library term made redundant is dropped, and every structured
   effect must lower the leave-one-window-out prediction error of its channels (``referee``);
   where a catalogue effect fails that check, the selection runs again without it;
4. refit with the chosen effects: parameters with sigmas, residuals before/after (``refit``);
   a library term that changes within a window (in temperature or time) is first removed
   from the window noise and the model refitted under it (``within_window``);
5. where the first-order residuals are largest and what they correlate with
   (``residuals``, ``regressors``); whether the final model still fails the recording's
   noise (``unexplained``: χ² whole, per channel, channels against each other); effects and
   terms the recording cannot tell apart (``confounding``).
"""

from __future__ import annotations

import numpy as np

from bench.diagnosis.bench_families import static_line_findings, static_lines
from bench.diagnosis.confounding import confounded, discovery, why
from bench.diagnosis.effects import EFFECTS, NEEDS_TABLE, WITH_LIBRARY, Candidate, pose_response
from bench.diagnosis.effects.base import first_order_design
from bench.diagnosis.effects.settling import settling_duration, settling_test
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.hysteresis import with_last_move
from bench.diagnosis.library import EFFECT, LibraryTerm, library_terms
from bench.diagnosis.library import candidate as library_candidate
from bench.diagnosis.likelihood import NoiseParams
from bench.diagnosis.model_state import ModelState, scale_matrix
from bench.diagnosis.pose_quantisation import quantisation_covariance
from bench.diagnosis.referee import prune_catalogue, referee
from bench.diagnosis.refit import ModelFit, effect_parameters, model_sequence
from bench.diagnosis.regressors import correlations
from bench.diagnosis.residuals import summarise, where
from bench.diagnosis.result import Diagnosis, Finding, ModelSummary
from bench.diagnosis.selection import select
from bench.diagnosis.summaries import summary
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.diagnosis.unexplained import unexplained
from bench.diagnosis.within_window import refit_within_window

__all__ = ["Diagnosis", "StaticEvidence", "Thresholds", "diagnose"]

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


def diagnose(
    ev: StaticEvidence,
    *,
    unit: str = "",
    channel_unit: str = "",
    source: str = "",
    use_library: bool = True,
    thresholds: Thresholds = THRESHOLDS,
) -> Diagnosis:
    """Diagnose a static recording (module docstring).

    :param ev: the recording's static evidence.
    :param use_library: search the term library beyond the catalogue (``library``).
    :param thresholds: the diagnosis's knobs (``thresholds``): the selection's false-alarm
        probability per step, the settling test's share of it, and, for
        ``orientation_known=False`` evidence, ``free_orientation_rad``, the standard deviation
        given to each window's orientation about the two axes perpendicular to gravity.
    :returns: :class:`~bench.diagnosis.result.Diagnosis`.
    :raises ValueError: fewer than 5 windows (10 orientation-free), or a pose set that cannot
        identify bias and K.
    """
    th = thresholds
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
    beside_library: list[Candidate] = []
    pose_ok = settle_ok = False
    for eff in EFFECTS:
        ok, reason = eff.observable(ev, th)
        if eff.id in NEEDS_TABLE and not ev.has_table:
            ok, reason = False, NO_TABLE_REASON
        if not ok:
            unobservable[eff.id] = reason
        elif eff.kind == "columns":
            (beside_library if eff.id in WITH_LIBRARY else pool).extend(eff.candidates(ev, th))
        elif eff.kind == "variance":
            pose_ok = True
        elif eff.kind == "window":
            settle_ok = True
    fixed = None
    if not ev.orientation_known:
        K0 = np.asarray(np.linalg.lstsq(X0, ev.y.reshape(-1), rcond=None)[0][3:12], dtype=float).reshape(3, 3)
        J = pose_response(ev, K0)
        fixed = th.free_orientation_rad**2 * np.einsum("wik,wjk->wij", J, J)
    quantised = quantisation_covariance(ev, th=th)  # the encoders' step as pose scatter
    if quantised is not None:
        fixed = quantised if fixed is None else fixed + quantised
    lib_terms: dict[str, LibraryTerm] = {}
    if ev.orientation_known and use_library:
        terms, _ = library_terms(ev, th)
        lib_terms = {f"{EFFECT}:{t.label}": t for t in terms}
    elif not ev.orientation_known:
        unobservable[EFFECT] = (
            "the library's terms need the specific force the recording says each window saw; an "
            "orientation-free diagnosis has only the magnitude of each reading"
        )
    library = [*beside_library, *(library_candidate(t) for t in lib_terms.values())]
    simplicity = {t.label: t.degree for t in lib_terms.values()}

    def select_without(excluded: set[str]) -> tuple[ModelState, dict[str, str]]:
        return select(
            ev,
            [c for c in pool if c.effect not in excluded],
            pose_allowed=pose_ok,
            fixed=fixed,
            library=library,
            simplicity=simplicity,
            th=th,
        )

    state, notes = select_without(set())
    assert state.fit is not None and state.noise is not None
    dropped = prune_catalogue(ev, state, pool, fixed, notes, th)
    if dropped:
        # the library's terms were chosen beside the dropped effects: choose them again without
        state, notes2 = select_without(set(dropped))
        notes.update({k: v for k, v in notes2.items() if k not in notes})
    refused = [e for e in referee(ev, state, fixed, notes, th) if not e.startswith(EFFECT + ":")]
    if refused:
        # a catalogue effect that fails the out-of-sample check is not a candidate: it may have
        # entered before, and bent the search of, a library term that explains what it mimicked
        excluded = {*dropped, *refused}
        state, notes2 = select_without(excluded)
        notes = {**notes2, **{k: v for k, v in notes.items() if k in excluded}}
        referee(ev, state, fixed, notes, th)
    # a library term that changes within a window (in temp or t) is not window noise: the
    # final model is refitted under the window noise without it (``within_window``)
    ev_final, state = refit_within_window(ev, state, lib_terms, fixed, th)
    assert state.fit is not None and state.noise is not None
    K = scale_matrix(state.fit)
    order = list(dict.fromkeys(s.effect for s in state.steps))
    seq = model_sequence(ev_final, order, state.candidates, state.pose, state.noise, K, fixed)
    final = seq[-1]
    span = float(np.ptp(ev.mid_s))
    alike = confounded(ev, K, state.candidates, pool, th)
    findings = []
    discovered = []
    for k, effect in enumerate(order):
        if effect in lib_terms:
            discovered.append(
                discovery(
                    ev_final, lib_terms[effect], final, seq, k, K, state, channel_unit, lib_terms, pool, th
                )
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
        conf = alike.get(effect, {})
        if conf:
            text += "; on this recording it cannot be told from " + ", ".join(
                f"{other} (signatures alike, |cos| = {cos:.2f}{why(ev, effect, other)})"
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
                explanation=next(e.explanation for e in EFFECTS if e.id == effect),
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
    # the bench-physics stage: periodic lines in the windows' samples (``bench_families``)
    lines, line_free = static_lines(ev, th)
    if settle_ok:
        assert line_free is not None and ev.sample_rate_hz is not None
        st = settling_test(line_free, ev.sample_rate_hz, th)
        if st.p_value < th.settling_share * th.false_alarm:
            params_s: dict[str, object] = {
                "frequency_hz": st.frequency_hz,
                "early_power_ratio": st.early_power_ratio,
            }
            sigma_s: dict[str, object] = {}
            try:
                dur, dur_sigma = settling_duration(line_free, ev.sample_rate_hz, st.frequency_hz, th)
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
                    explanation=next(e.explanation for e in EFFECTS if e.id == "settling"),
                )
            )
    findings.extend(static_line_findings(ev, lines, channel_unit, float(np.sqrt(np.mean(final.resid**2)))))
    base = _summary(seq[0])
    rs = summarise(ev_final, seq[0].resid, seq[0].sigma)
    left = with_last_move(
        ev_final, final, state, K, fixed, unexplained(ev_final, final, state, K, fixed, th), th
    )
    claimed = bool(findings or discovered or left is not None)
    return Diagnosis(
        unit=unit,
        channel_unit=channel_unit,
        method="static" if ev.orientation_known else "orientation-free",
        baseline=base,
        final=_summary(final),
        findings=tuple(findings),
        channel_ratio=rs.channel_ratio,
        where=where(ev_final, rs, th.where_ratio, claimed),
        correlations=tuple(correlations(ev_final, seq[0].resid, seq[0].sigma, th)),
        unobservable=unobservable,
        notes=(*note_list, _noise_text(state.noise)),
        noise_text=_noise_text(state.noise),
        labels=ev.labels,
        mid_s=ev.mid_s,
        bias=state.fit.theta[:3].copy(),
        K=K,
        source=source,
        discovered=tuple(discovered),
        unexplained=left,
    )
