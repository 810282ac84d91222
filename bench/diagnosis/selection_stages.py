"""The forward selection as a window-means stage, and how a check after it goes on: the
selection resumed without the effects it took out, or run again under a carried excess."""

from __future__ import annotations

from dataclasses import replace

from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.library import candidate as library_candidate
from bench.diagnosis.pipeline import Notes
from bench.diagnosis.selection import select
from bench.diagnosis.thresholds import Thresholds
from bench.diagnosis.window_state import WindowState


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
        fixed=st.fixed,
        library=library,
        excluded=st.excluded,
        simplicity={t.label: t.degree for t in st.lib_terms.values()},
        th=th,
        excess=st.carried,
    )
    return replace(st, selection=sel, model=sel.model), sel.notes


def resumed(st: WindowState, out: list[str]) -> tuple[WindowState, dict[str, str]]:
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


def rerun(
    ev: StaticEvidence, st: WindowState, out: list[str], carried: FloatArray, th: Thresholds
) -> tuple[WindowState, dict[str, str]]:
    """As ``resumed``, but the selection run again from its start with each channel's own excess
    ``carried`` (3,) in its noise, re-estimated at every step (every step's noise changes, not
    only those after the claim)."""
    assert st.selection is not None
    stale = st.selection.notes
    kept = {k: v for k, v in st.notes.items() if stale.get(k) != v}
    again = replace(st, carried=carried, excluded=st.excluded | set(out), notes=kept)
    ran, notes = forward_selection(ev, again, th)
    return ran, dict(notes)
