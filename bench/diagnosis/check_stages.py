"""The backward checks of the selected model that resume the selection without what they
take out: redundant catalogue effects and claims refused out of sample."""

from __future__ import annotations

from dataclasses import replace

from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.library import EFFECT
from bench.diagnosis.pipeline import Notes
from bench.diagnosis.referee import prune_catalogue, referee
from bench.diagnosis.selection_stages import resumed
from bench.diagnosis.thresholds import Thresholds
from bench.diagnosis.window_state import WindowState


def prune_redundant(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Backward removal of the catalogue (``referee.prune_catalogue``). Rule: a catalogue effect
    whose Wald statistic, once the library's terms are in, falls below the gate it passed to
    enter is dropped, and the selection resumes without it from the step before it entered
    (``greedy.resume``: the library's terms after it were chosen beside it)."""
    assert st.model is not None
    notes: dict[str, str] = {}
    model = st.model.copy()
    dropped = prune_catalogue(ev, model, list(st.pool), st.fixed, notes, th)
    if not dropped:
        return replace(st, model=model), notes
    out, again = resumed(st, dropped)
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
    refused = [e for e in referee(ev, model, st.fixed, notes, th) if not e.startswith(EFFECT + ":")]
    if not refused:
        return replace(st, model=model), notes
    out, again = resumed(st, refused)
    fresh = {**again, **{k: v for k, v in notes.items() if k in refused}}
    assert out.model is not None
    referee(ev, out.model, out.fixed, fresh, th)
    return out, fresh
