"""The state of a window-means diagnosis: what its stages (``stages``) have decided so far."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from bench.diagnosis.effects import Candidate
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.excess_referee import HeadToHead
from bench.diagnosis.library import LibraryTerm
from bench.diagnosis.model_state import ModelState, scale_matrix
from bench.diagnosis.periodic_lines import Line
from bench.diagnosis.pipeline import Notes
from bench.diagnosis.refit import ModelFit
from bench.diagnosis.result import Finding, Unexplained
from bench.diagnosis.selection import Selection


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
    :param carried: (3,) each channel's own excess ε̂_c² that won a head to head
        (``excess_head_to_head``; channel units², zero on a channel that did not win), held in
        the selection's noise as a variance component re-estimated with the other noise terms
        (the report reads the final model without it), or ``None``.
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
    def scale(self) -> FloatArray:
        """(3, 3) the model's scale matrix."""
        assert self.model is not None and self.model.fit is not None
        return scale_matrix(self.model.fit)
