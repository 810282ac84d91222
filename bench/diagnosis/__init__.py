"""Diagnosis: where a recording and the first-order model differ, which physics was left out.

``diagnose(evidence)`` runs the pipeline of the evidence's kind (``stages.pipeline_for``:
static, static without the library, orientation-free) over a static or hand-held recording's
window means, then reports from the final state (a moving-table recording goes to
:func:`bench.diagnosis.dynamic.diagnose_dynamic` instead: the same method, its own stages,
``moving_stages``). The stages, one rule each
(``stages``, docs/diagnose.md "Following one recording through the stages"):

1. ``screen_catalogue``: observability of every effect on this recording (``effects``);
2. ``orientation_prior`` (orientation-free), ``library_search`` (``library``);
3. ``forward_selection``, ``prune_redundant``, ``out_of_sample_referee``: the one selection
   core (``greedy``: forward addition under an F gate and BIC, backward removal, and the
   selection resumed from the step before an effect a check took out) through ``selection``
   and ``referee``;
4. ``within_window``, ``refit_sequence`` (``within_window``, ``refit``);
5. ``bench_lines``, ``settling``, ``unexplained_stage`` (``bench_families``, ``effects.settling``,
   ``unexplained``, ``hysteresis``).

The report: parameters with sigmas, each finding's BIC change in the sequence, effects the
recording cannot tell apart (``confounding``), where the first-order residuals are largest and
what they correlate with (``residuals``, ``regressors``).
"""

from __future__ import annotations

import numpy as np

from bench.diagnosis.bench_families import static_line_findings
from bench.diagnosis.confounding import confounded, discovery, why
from bench.diagnosis.effects import EFFECTS
from bench.diagnosis.effects.base import first_order_design
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import NoiseParams
from bench.diagnosis.refit import ModelFit, effect_parameters
from bench.diagnosis.regressors import correlations
from bench.diagnosis.residuals import summarise, where
from bench.diagnosis.result import Diagnosis, Finding, ModelSummary
from bench.diagnosis.screen_stages import NO_TABLE_REASON
from bench.diagnosis.stages import pipeline_for
from bench.diagnosis.summaries import summary
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.diagnosis.window_state import WindowState

__all__ = ["NO_TABLE_REASON", "Diagnosis", "StaticEvidence", "Thresholds", "diagnose"]


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
    st, _ = pipeline_for(ev, use_library).run(ev, WindowState(), th)
    state, ev_final, seq, K = st.model, st.ev_final, st.seq, st.scale
    assert state is not None and state.fit is not None and state.noise is not None and ev_final is not None
    lib_terms, pool = st.lib_terms, list(st.pool)
    final = seq[-1]
    span = float(np.ptp(ev.mid_s))
    alike = confounded(ev, K, state.candidates, pool, th)
    findings = []
    discovered = []
    for k, effect in enumerate(st.order):
        if effect in lib_terms:
            discovered.append(
                discovery(
                    ev_final,
                    lib_terms[effect],
                    final,
                    list(seq),
                    k,
                    K,
                    state,
                    channel_unit,
                    lib_terms,
                    pool,
                    th,
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
                    else next(step.delta_bic for step in state.steps if step.effect == "pose_error")
                ),
                lr=float(sum(s.lr for s in state.steps if s.effect == effect)),
                residual_rms_after=float(np.sqrt(np.mean(seq[k + 1].resid ** 2))),
                explanation=next(e.explanation for e in EFFECTS if e.id == effect),
                confounded_with=tuple(sorted(conf)),
            )
        )
    note_list = [f"{label}: {text}" for label, text in sorted(st.notes.items())]
    for f in findings:
        if f.confounded_with:
            note_list.append(
                f"{f.effect} fits this recording about as well as {', '.join(f.confounded_with)}: "
                "the recording cannot tell them apart (see the finding's summary)"
            )
    findings.extend(st.extra)
    findings.extend(static_line_findings(ev, st.lines, channel_unit, float(np.sqrt(np.mean(final.resid**2)))))
    base = _summary(seq[0])
    rs = summarise(ev_final, seq[0].resid, seq[0].sigma)
    left = st.left
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
        unobservable=st.unobservable,
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
