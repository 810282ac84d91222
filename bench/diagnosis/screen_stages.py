"""The window-means stages before the selection: what the recording can show and the fixed
noise it carries (each ``stage(evidence, state, thresholds) -> (state, notes)``, ``stages``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.diagnosis.effects import EFFECTS, WITH_LIBRARY, Candidate, pose_response
from bench.diagnosis.effects.base import first_order_design
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.library import EFFECT, library_terms
from bench.diagnosis.pipeline import Notes
from bench.diagnosis.pose_quantisation import quantisation_covariance
from bench.diagnosis.thresholds import Thresholds
from bench.diagnosis.window_state import WindowState

NO_TABLE_REASON = (
    "needs a table (its motion, encoders, base or ringing after a move); this recording has no table"
)


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
