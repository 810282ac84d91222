"""Each claim against "unexplained on one channel" (``excess_referee``) as a window-means stage:
the withdrawals, and the excess that won carried into the selection's noise."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.excess_referee import HeadToHead, excess_referee
from bench.diagnosis.likelihood import NoiseParams
from bench.diagnosis.pipeline import Notes
from bench.diagnosis.referee import referee
from bench.diagnosis.selection_stages import rerun, resumed
from bench.diagnosis.thresholds import Thresholds
from bench.diagnosis.window_state import WindowState


def excess_head_to_head(ev: StaticEvidence, st: WindowState, th: Thresholds) -> tuple[WindowState, Notes]:
    """Head to head with "unexplained on one channel" (``excess_referee``). Rule: each claim of
    the model (a catalogue effect, a library term, the pose error) must predict a left-out window
    (log predictive density) better than the model without it where a channel carries its own
    excess variance (a channel the claim acts on; any channel for the pose error); one that does
    not is withdrawn and no longer a candidate. Where a channel's excess won, that excess ε̂_c²
    (per window, on channel c) is carried into the selection's noise (``carried``) as a variance
    component that REML re-estimates with the other noise terms at every step, and the
    selection runs again with it, so a later candidate on that channel is judged against a
    model that holds the excess, and a claim that enters can take over what the excess held
    (and the excess what a claim held); otherwise the selection resumes without the claim from
    the step before it entered (``greedy.resume``). The out-of-sample referee judges that model,
    which is then judged the same way; the channel is flagged unexplained
    (``unexplained_stage``)."""
    assert st.model is not None
    notes: dict[str, str] = {}
    model = st.model.copy()
    withdrawn = excess_referee(ev, model, st.fixed, notes, th)
    if not withdrawn:
        return replace(st, model=model), notes
    lost = (*st.lost, *withdrawn)
    carried = carry(model.noise, st.carried, withdrawn)
    if carried is None or carried is st.carried:
        out, again = resumed(st, [h.effect for h in withdrawn])
    else:
        out, again = rerun(ev, st, [h.effect for h in withdrawn], carried, th)
    assert out.model is not None
    taken = {c.effect for c in out.model.candidates}
    assert not taken & out.excluded, "a withdrawn claim re-entered"
    fresh = {**again, **notes}
    referee(ev, out.model, out.fixed, fresh, th)
    out = replace(out, lost=lost)
    more, later = excess_head_to_head(ev, out.noted(fresh), th)
    return more, {**fresh, **later}


def carry(noise: NoiseParams | None, carried: FloatArray | None, lost: list[HeadToHead]) -> FloatArray | None:
    """The (3,) start of each channel's own excess for the selection run again (channel units²):
    for each channel whose own excess won a head to head in ``lost``, the largest such ε̂_c²
    added to the model's current estimate ``noise.excess_var`` (each ε̂_c² was estimated beside
    it, so the two add); a channel carried before keeps its estimate (or, where REML took it to
    zero, its earlier start: it stays a component to estimate). ``carried`` itself when no
    channel won."""
    won: dict[int, float] = {}
    for h in lost:
        if h.channel is not None and h.excess_var > 0:
            won[h.channel] = max(won.get(h.channel, 0.0), h.excess_var)
    if not won:
        return carried
    now = (
        np.zeros(3)
        if noise is None or noise.excess_var is None
        else np.asarray(noise.excess_var, dtype=float)
    )
    before = np.zeros(3) if carried is None else carried
    out = np.where(now > 0, now, before)
    for c, var in won.items():
        out[c] = now[c] + var
    return out
