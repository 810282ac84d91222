"""The stages of a window-means diagnosis (static, hand-held, orientation-free), one rule each.

Each stage is ``stage(evidence, state, thresholds) -> (state, notes)`` (``pipeline``); the
pipelines at the end of this module put them in order for each kind of recording. The model
selection stages all call the one selection core (``greedy``, through ``selection.select``
and ``referee``); the report (``bench.diagnosis.diagnose``) is built from the final state.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from bench.diagnosis.bench_families import static_lines
from bench.diagnosis.effects import EFFECTS, WITH_LIBRARY, Candidate, pose_response
from bench.diagnosis.effects.base import FloatArray, first_order_design
from bench.diagnosis.effects.settling import settling_duration, settling_test
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.excess_referee import HeadToHead, excess_referee, flag_instead
from bench.diagnosis.hysteresis import with_last_move
from bench.diagnosis.library import EFFECT, LibraryTerm, library_terms
from bench.diagnosis.library import candidate as library_candidate
from bench.diagnosis.model_state import ModelState, fit_model, scale_matrix
from bench.diagnosis.periodic_lines import Line
from bench.diagnosis.pipeline import Notes, Pipeline
from bench.diagnosis.pose_quantisation import quantisation_covariance
from bench.diagnosis.referee import prune_catalogue, referee
from bench.diagnosis.refit import ModelFit, model_sequence
from bench.diagnosis.result import Finding, Unexplained
from bench.diagnosis.selection import Selection, select
from bench.diagnosis.summaries import summary
from bench.diagnosis.thresholds import Thresholds
from bench.diagnosis.unexplained import unexplained
from bench.diagnosis.within_window import refit_within_window

NO_TABLE_REASON = (
    "needs a table (its motion, encoders, base or ringing after a move); this recording has no table"
)


@dataclass(frozen=True)
class WindowState:
    """What the stages of a window-means diagnosis have decided so far.

    :param unobservable: effect -> why this recording cannot show it.
    :param pool: the catalogue's fixed-column candidates; :param beside_library: candidates
        searched with the library (``effects.WITH_LIBRARY``); :param lib_terms: the library's
        terms beyond the catalogue, by effect label.
    :param pose_ok: the pose error (a variance component) may be tried; :param settle_ok: the
        settling test (a window test) may run.
    :param fixed: (m, 3, 3) fixed extra covariance per window (orientation-free), or ``None``.
    :param carried: (m, 3, 3) each channel's own excess ε̂_c² that won a head to head
        (``excess_head_to_head``), added to ``fixed`` in the selection's noise only (the report
        reads the final model under ``fixed``), or ``None``.
    :param selection: the forward selection with its path (``selection.Selection``), resumed
        when a check takes a catalogue effect out; :param model: the selected model after the
        checks; :param excluded: catalogue effects no longer candidates (dropped as redundant or
        refused out of sample).
    :param ev_final: the evidence the final model is reported from (``within_window``).
    :param order: effects in the order they entered; :param seq: the first-order model, then each
        effect added in turn, under the final noise.
    :param lines: periodic lines in the windows' samples; :param line_free: the samples without them.
    :param extra: findings of the window tests (settling).
    :param left: what the final model leaves unexplained, or ``None``.
    :param lost: catalogue claims withdrawn for a channel's own excess (``excess_referee``).
    :param notes: label -> why it was set aside.
    """

    unobservable: dict[str, str] = field(default_factory=dict)
    pool: tuple[Candidate, ...] = ()
    beside_library: tuple[Candidate, ...] = ()
    lib_terms: dict[str, LibraryTerm] = field(default_factory=dict)
    pose_ok: bool = False
    settle_ok: bool = False
    fixed: FloatArray | None = None
    carried: FloatArray | None = None
    selection: Selection | None = None
    model: ModelState | None = None
    excluded: frozenset[str] = frozenset()
    ev_final: StaticEvidence | None = None
    order: tuple[str, ...] = ()
    seq: tuple[ModelFit, ...] = ()
    lines: tuple[Line, ...] = ()
    line_free: tuple[FloatArray, ...] | None = None
    extra: tuple[Finding, ...] = ()
    left: Unexplained | None = None
    lost: tuple[HeadToHead, ...] = ()
    notes: dict[str, str] = field(default_factory=dict)

    def noted(self, notes: Notes) -> WindowState:
        """The state with ``notes`` added (a label's later note replaces an earlier one)."""
        return replace(self, notes={**self.notes, **notes}) if notes else self

    @property
    def selection_fixed(self) -> FloatArray | None:
        """(m, 3, 3) the fixed covariance per window the selection and its checks read: ``fixed``
        and the excess carried from the head to heads."""
        if self.carried is None:
            return self.fixed
        return self.carried if self.fixed is None else self.fixed + self.carried

    @property
    def scale(self) -> FloatArray:
        """(3, 3) the model's scale matrix."""
        assert self.model is not None and self.model.fit is not None
        return scale_matrix(self.model.fit)


def screen_catalogue(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Catalogue screen. Rule: an effect is a candidate only where the recording can show it
    (its observability condition under ``th``) and, when its physics is the table's
    (``needs_table``), only where the recording has a table; each candidate goes where its kind
    is tested (design columns to the selection, the variance component and the window test to
    their stages)."""
    unobservable: dict[str, str] = {}
    pool: list[Candidate] = []
    beside: list[Candidate] = []
    pose_ok = settle_ok = False
    for eff in EFFECTS:
        ok, reason = eff.observable(ev, th)
        if eff.needs_table and not ev.has_table:
            ok, reason = False, NO_TABLE_REASON
        if not ok:
            unobservable[eff.id] = reason
        elif eff.kind == "columns":
            (beside if eff.id in WITH_LIBRARY else pool).extend(eff.candidates(ev, th))
        elif eff.kind == "variance":
            pose_ok = True
        elif eff.kind == "window":
            settle_ok = True
    out = replace(
        st,
        unobservable={**st.unobservable, **unobservable},
        pool=tuple(pool),
        beside_library=tuple(beside),
        pose_ok=pose_ok,
        settle_ok=settle_ok,
    )
    return out, {}


def orientation_prior(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Orientation prior. Rule: where only the magnitude of each reading is evidence, each
    window's orientation about the two axes perpendicular to gravity gets a standard deviation
    of ``th.free_orientation_rad``, a fixed covariance J Jᵀ σ² per window (J the pose response
    at the first-order fit's K)."""
    if ev.orientation_known:
        return st, {}
    X0 = first_order_design(ev.f_m_s2)
    K0 = np.asarray(np.linalg.lstsq(X0, ev.y.reshape(-1), rcond=None)[0][3:12], dtype=float).reshape(3, 3)
    J = pose_response(ev, K0)
    return replace(st, fixed=th.free_orientation_rad**2 * np.einsum("wik,wjk->wij", J, J)), {}


def encoder_quantisation(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Encoder step (``pose_quantisation``). Rule: encoders that read in steps of q (the
    sidecar's ``encoder_resolution_deg``) leave a pose scatter of q²/12 per encoder angle, carried
    through K·∂f/∂θ into each window's covariance as a fixed term; nothing without a declared step."""
    quantised = quantisation_covariance(ev, th=th)
    if quantised is None:
        return st, {}
    return replace(st, fixed=quantised if st.fixed is None else st.fixed + quantised), {}


def library_search(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Library screen. Rule: the term library's candidates are the monomials of the recording's
    bases that its pose set determines (``library.library_terms``). On an orientation-free
    recording the specific force is each reading's direction from the scalar fit (its error,
    ~1e-4 rad at the simulated noise, moves a cubic term by far less than the noise) and only
    the magnitude of a term's signature is evidence (the free orientation takes the rest):
    a cubic on one axis of a hand-held unit is named there like on a table."""
    terms, _ = library_terms(ev, th)
    return replace(st, lib_terms={f"{EFFECT}:{t.label}": t for t in terms}), {}


def forward_selection(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Greedy forward selection (``greedy.extend`` through ``selection.select``). Rule: at each
    step the catalogue, then the library, then a swap, then the pose error are asked; the first
    with a candidate whose statistic passes its gate (F at ``th.false_alarm`` / N; the library
    at ``th.library_share`` of it) and whose BIC change is negative makes the step."""
    library = [*st.beside_library, *(library_candidate(t) for t in st.lib_terms.values())]
    sel = select(
        ev,
        list(st.pool),
        pose_allowed=st.pose_ok,
        fixed=st.selection_fixed,
        library=library,
        excluded=st.excluded,
        simplicity={t.label: t.degree for t in st.lib_terms.values()},
        th=th,
    )
    return replace(st, selection=sel, model=sel.model), sel.notes


def _resumed(st: WindowState, out: list[str]) -> tuple[WindowState, dict[str, str]]:
    """The state with the selection resumed without the effects ``out``
    (``selection.Selection.without``): its model, and the notes with the abandoned steps'
    notes replaced by the resumed path's. Effects taken out before stay out: a resume that goes
    back to a step before an earlier one's would otherwise start from a state that still had
    them as candidates."""
    assert st.selection is not None
    excluded = st.excluded | set(out)
    sel = st.selection.without(excluded)
    stale = st.selection.notes
    kept = {k: v for k, v in st.notes.items() if stale.get(k) != v}
    return replace(st, selection=sel, model=sel.model, excluded=excluded, notes=kept), sel.notes


def _rerun(
    ev: StaticEvidence, st: WindowState, out: list[str], carried: FloatArray, th: Thresholds
) -> tuple[WindowState, dict[str, str]]:
    """As ``_resumed``, but the selection run again from its start under the noise with the
    excess ``carried`` (every step's noise changes, not only those after the claim)."""
    assert st.selection is not None
    stale = st.selection.notes
    kept = {k: v for k, v in st.notes.items() if stale.get(k) != v}
    again = replace(st, carried=carried, excluded=st.excluded | set(out), notes=kept)
    ran, notes = forward_selection(ev, again, th)
    return ran, dict(notes)


def prune_redundant(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Backward removal of the catalogue (``referee.prune_catalogue``). Rule: a catalogue effect
    whose Wald statistic, once the library's terms are in, falls below the gate it passed to
    enter is dropped, and the selection resumes without it from the step before it entered
    (``greedy.resume``: the library's terms after it were chosen beside it)."""
    assert st.model is not None
    notes: dict[str, str] = {}
    model = st.model.copy()
    dropped = prune_catalogue(ev, model, list(st.pool), st.selection_fixed, notes, th)
    if not dropped:
        return replace(st, model=model), notes
    out, again = _resumed(st, dropped)
    return out, {**again, **notes}


def out_of_sample_referee(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Out-of-sample referee (``referee.referee``). Rule: every structured effect must lower the
    leave-one-window-out prediction error of its channels; the worst offender is removed until
    all do. A catalogue effect refused is no longer a candidate: the selection resumes without
    it from the step before it entered (``greedy.resume``; it may have bent the library's
    search) and the referee judges that model."""
    assert st.model is not None
    notes: dict[str, str] = {}
    model = st.model.copy()
    refused = [e for e in referee(ev, model, st.selection_fixed, notes, th) if not e.startswith(EFFECT + ":")]
    if not refused:
        return replace(st, model=model), notes
    out, again = _resumed(st, refused)
    fresh = {**again, **{k: v for k, v in notes.items() if k in refused}}
    assert out.model is not None
    referee(ev, out.model, out.selection_fixed, fresh, th)
    return out, fresh


def excess_head_to_head(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Head to head with "unexplained on one channel" (``excess_referee``). Rule: each claim of
    the model (a catalogue effect, a library term, the pose error) must predict a left-out window
    (log predictive density) better than the model without it where a channel carries its own
    excess variance (a channel the claim acts on; any channel for the pose error); one that does
    not is withdrawn and no longer a candidate. Where a channel's excess won, that excess ε̂_c²
    (per window, on channel c) is carried into the selection's noise (``carried``) and the
    selection runs again under it, so a later candidate on that channel is judged against a
    model that already holds the excess; otherwise the selection resumes without the claim from
    the step before it entered (``greedy.resume``). The out-of-sample referee judges that model,
    which is then judged the same way; the channel is flagged unexplained
    (``unexplained_stage``)."""
    assert st.model is not None
    notes: dict[str, str] = {}
    model = st.model.copy()
    withdrawn = excess_referee(ev, model, st.selection_fixed, notes, th)
    if not withdrawn:
        return replace(st, model=model), notes
    lost = (*st.lost, *withdrawn)
    carried = _carry(ev, st.carried, withdrawn)
    if carried is None or carried is st.carried:
        out, again = _resumed(st, [h.effect for h in withdrawn])
    else:
        out, again = _rerun(ev, st, [h.effect for h in withdrawn], carried, th)
    assert out.model is not None
    taken = {c.effect for c in out.model.candidates}
    assert not taken & out.excluded, "a withdrawn claim re-entered"
    fresh = {**again, **notes}
    referee(ev, out.model, out.selection_fixed, fresh, th)
    out = replace(out, lost=lost)
    more, later = excess_head_to_head(ev, out.noted(fresh), th)
    return more, {**fresh, **later}


def _carry(ev: StaticEvidence, carried: FloatArray | None, lost: list[HeadToHead]) -> FloatArray | None:
    """``carried`` with, for each channel whose own excess won a head to head in ``lost``, the
    largest such ε̂_c² added on that channel in every window ((m, 3, 3), channel units²); each
    ε̂_c² was estimated beside the excess already carried, so the two add. ``carried`` itself
    when no channel won."""
    won: dict[int, float] = {}
    for h in lost:
        if h.channel is not None and h.excess_var > 0:
            won[h.channel] = max(won.get(h.channel, 0.0), h.excess_var)
    if not won:
        return carried
    out = np.zeros((ev.y.shape[0], 3, 3)) if carried is None else carried.copy()
    for c, var in won.items():
        out[:, c, c] += var
    return out


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
            ev, model.candidates, model.pose, scale_matrix(model.fit), st.fixed, model.noise, th=th
        )
        model = replace(model.copy(), noise=noise, fit=fit)
    ev_final, model = refit_within_window(ev, model, st.lib_terms, st.fixed, th)
    return replace(st, ev_final=ev_final, model=model), {}


def refit_sequence(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Model sequence (``refit.model_sequence``). Rule: the first-order model, then each chosen
    effect added in the order it entered, all under the final model's noise, so each effect's
    BIC change and residual are read against the same covariance."""
    assert st.model is not None and st.model.noise is not None and st.ev_final is not None
    m, noise = st.model, st.model.noise
    order = tuple(dict.fromkeys(s.effect for s in m.steps))
    seq = model_sequence(st.ev_final, list(order), m.candidates, m.pose, noise, st.scale, st.fixed)
    return replace(st, order=order, seq=tuple(seq)), {}


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


_SELECT = (forward_selection, prune_redundant, out_of_sample_referee, excess_head_to_head)
_REPORT = (within_window, refit_sequence, bench_lines, settling, unexplained_stage)

STATIC: Pipeline[StaticEvidence, WindowState] = Pipeline(
    "static", (screen_catalogue, encoder_quantisation, library_search, *_SELECT, *_REPORT)
)
"""Windows whose specific force the recording knows (a table's encoders, or hand-held poses
labelled ``nominal_up``: the screen sets the table's effects aside when there is no table)."""

STATIC_NO_LIBRARY: Pipeline[StaticEvidence, WindowState] = Pipeline(
    "static, catalogue only", (screen_catalogue, encoder_quantisation, *_SELECT, *_REPORT)
)
"""As :data:`STATIC` without the term library (``diagnose(use_library=False)``)."""

ORIENTATION_FREE: Pipeline[StaticEvidence, WindowState] = Pipeline(
    "orientation-free",
    (screen_catalogue, orientation_prior, encoder_quantisation, library_search, *_SELECT, *_REPORT),
)
"""Windows whose orientation the recording does not know: only each reading's magnitude."""


def pipeline_for(ev: StaticEvidence, use_library: bool = True) -> Pipeline[StaticEvidence, WindowState]:
    """The pipeline of the evidence's kind."""
    if not ev.orientation_known:
        return ORIENTATION_FREE
    return STATIC if use_library else STATIC_NO_LIBRARY
