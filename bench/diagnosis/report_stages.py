"""The window-means stages after the selection: the final model refitted for the report, the
window tests and what the model leaves unexplained."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.diagnosis.bench_families import static_lines
from bench.diagnosis.effects import EFFECTS
from bench.diagnosis.effects.settling import settling_duration, settling_test
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.excess_referee import flag_instead
from bench.diagnosis.hysteresis import with_last_move
from bench.diagnosis.likelihood import without_excess
from bench.diagnosis.model_state import fit_model, scale_matrix
from bench.diagnosis.pipeline import Notes
from bench.diagnosis.profiled import reprofiled
from bench.diagnosis.refit import model_sequence
from bench.diagnosis.result import Finding
from bench.diagnosis.summaries import summary
from bench.diagnosis.thresholds import Thresholds
from bench.diagnosis.unexplained import unexplained
from bench.diagnosis.window_state import WindowState
from bench.diagnosis.within_window import refit_within_window


def within_window(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Within-window refit (``within_window``). Rule: a library term that changes within a window
    (in temperature or time) is not window noise: the window noise is estimated without it and
    the model refitted under that noise."""
    assert st.model is not None
    model = st.model
    if st.carried is not None:
        # the report reads the model under ``fixed`` alone: its noise again without the carried excess
        assert model.noise is not None and model.fit is not None
        noise, fit, _ = fit_model(
            ev,
            model.candidates,
            model.pose,
            scale_matrix(model.fit),
            st.fixed,
            without_excess(model.noise),
            th=th,
        )
        model = replace(model.copy(), noise=noise, fit=fit)
    ev_final, model = refit_within_window(ev, model, st.lib_terms, st.fixed, th)
    return replace(st, ev_final=ev_final, model=model), {}


def refit_sequence(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Model sequence (``refit.model_sequence``). Rule: the first-order model, then each chosen
    effect added in the order it entered, all under the final model's noise, so each effect's
    BIC change and residual are read against the same covariance; a profiled parameter (a
    thermal lag's τ) is profiled again under the model's noise and the noise re-estimated with
    it, ``th.profile_passes`` times, first (``profiled.reprofiled``)."""
    assert st.model is not None and st.model.noise is not None and st.ev_final is not None
    m, noise = st.model, st.model.noise
    order = tuple(dict.fromkeys(s.effect for s in m.steps))
    if any(c.resolved_from is not None for c in m.candidates):
        fit = m.fit
        for _ in range(th.profile_passes):
            cands = reprofiled(st.ev_final, m.candidates, noise, st.scale, st.fixed, th)
            noise, fit, _ = fit_model(st.ev_final, cands, m.pose, st.scale, st.fixed, noise, th=th)
            m = replace(m, candidates=cands, noise=noise, fit=fit)
    seq = model_sequence(st.ev_final, list(order), m.candidates, m.pose, noise, st.scale, st.fixed)
    return replace(st, order=order, seq=tuple(seq), model=m), {}


def bench_lines(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Periodic lines (``bench_families.static_lines``). Rule: a line in the windows' samples is
    claimed where its periodogram peak passes the line test at ``th``; the samples are kept
    without it for the window tests (a line is not a ring after a move)."""
    lines, line_free = static_lines(ev, th)
    return replace(st, lines=lines, line_free=line_free), {}


def settling(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Settling (``effects.settling``). Rule: claimed where the early-excess test's p value
    (Bonferroni over its frequencies) is below ``th.settling_share`` · ``th.false_alarm``; its
    duration from the decay of the narrow-band power, where that can be measured."""
    if not st.settle_ok:
        return st, {}
    assert st.line_free is not None and ev.sample_rate_hz is not None and st.seq
    test = settling_test(st.line_free, ev.sample_rate_hz, th)
    if test.p_value >= th.settling_share * th.false_alarm:
        return st, {}
    params: dict[str, object] = {
        "frequency_hz": test.frequency_hz,
        "early_power_ratio": test.early_power_ratio,
    }
    sigma: dict[str, object] = {}
    notes: dict[str, str] = {}
    try:
        dur, dur_sigma = settling_duration(st.line_free, ev.sample_rate_hz, test.frequency_hz, th)
        params["duration_s"], sigma["duration_s"] = dur, dur_sigma
    except ValueError as exc:
        notes["settling"] = str(exc)
    lr = float(test.statistic - test.dof)
    finding = Finding(
        effect="settling",
        summary=summary("settling", params, sigma, ev.labels, float(np.ptp(ev.mid_s))),
        parameters=params,
        sigma=sigma,
        delta_bic=float(-lr + 2.0 * np.log(test.n_obs)),
        lr=lr,
        residual_rms_after=float(np.sqrt(np.mean(st.seq[-1].resid ** 2))),
        explanation=next(e.explanation for e in EFFECTS if e.id == "settling"),
    )
    return replace(st, extra=(*st.extra, finding)), notes


def unexplained_stage(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Unexplained (``unexplained``, ``hysteresis.with_last_move``). Rule: the final model's χ²
    whole, per channel and channel against channel is tested against the recording's noise at
    ``th.unexplained_alpha``; where it fails, where the misfit is and what it follows (the
    direction of the last move among them). A channel whose excess won a head to head against a
    claim (``excess_head_to_head``) is named there when the tests name none."""
    assert st.model is not None and st.ev_final is not None and st.seq
    final, K = st.seq[-1], st.scale
    left = unexplained(st.ev_final, final, st.model, K, st.fixed, th)
    left = flag_instead(st.ev_final, final, st.model, K, st.fixed, left, st.lost, th)
    return replace(st, left=with_last_move(st.ev_final, final, st.model, K, st.fixed, left, th)), {}
