"""A catalogue effect swapped for library terms where that lowers the BIC (``select``'s swap group).

A catalogue effect enters first, so one that only partly mimics a term beyond the catalogue
can enter and then bend the library's choice; ``swap_step`` takes it out and lets the library's
steps run again without it.
"""

from __future__ import annotations

from dataclasses import replace

from bench.diagnosis.column_step import LIB, structured_step
from bench.diagnosis.confounding import mimics
from bench.diagnosis.effects import Candidate
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.model_state import ModelState, Step, bic, fit_model
from bench.diagnosis.thresholds import Thresholds
from bench.diagnosis.wander_cap import SlowNoiseCap


def swap_step(
    ev: StaticEvidence,
    state: ModelState,
    K: FloatArray,
    fixed: FloatArray | None,
    library: list[Candidate],
    notes: dict[str, str],
    simplicity: dict[str, int] | None,
    cap: SlowNoiseCap,
    th: Thresholds,
) -> ModelState | None:
    """The model with a catalogue effect replaced by library terms where that lowers the BIC,
    or ``None``.

    A catalogue effect enters first, so one that only partly mimics a term beyond the
    catalogue can enter and then bend the library's choice. For each catalogue effect E of
    the model: remove it and the library's terms, run the library's steps again (their gate
    as in ``select``); if that model's BIC (−2 ℓ_ML + k ln n, each model under its own
    noise) is lower by more than ``th.tie_chi2`` (strong evidence: the catalogue keeps its
    precedence on anything weaker), the swap is made
    (E is not tried again). Where E's columns can mimic one of the terms (``confounding.mimics``), a
    catalogue effect that explains the data alone keeps it (a concealed cross-coupling is not
    given to an alike product that fits as well with fewer parameters); E and the terms then
    compete head to head only when the model needed library terms beside E on its channels,
    and the swap needs, besides that BIC, a model with no more parameters than the one it
    replaces (a cube taken for cross-coupling, with a term for what the cross-coupling left).
    """
    best: tuple[float, str, ModelState] | None = None
    current = bic(ev, state)
    for effect in dict.fromkeys(c.effect for c in state.candidates):
        if effect.startswith(LIB):
            continue
        keep = [c for c in state.candidates if c.effect != effect and c not in library]
        noise0, fit0, K0 = fit_model(ev, keep, state.pose, K, fixed, state.noise, cap=cap)
        trial = replace(
            state.copy(), candidates=keep, noise=noise0, fit=fit0,
            steps=[st for st in state.steps if st.effect != effect and not st.effect.startswith(LIB)],
        )  # fmt: skip
        added = 0
        while added < th.max_steps:
            n_lib = sum(1 for c in library if c not in trial.candidates)
            step = structured_step(
                ev, library, trial, K0, fixed, th.library_share * th.false_alarm / max(n_lib, 1), {},
                prescreen=th.prescreen, simplicity=simplicity, cap=cap, th=th,
            )  # fmt: skip
            if step is None:
                break
            dbic, chosen, lr, (noise1, fit1, K0) = step
            trial.candidates = [*trial.candidates, chosen]
            trial.steps.append(Step(chosen.label, chosen.effect, lr, dbic, len(chosen.names)))
            trial.noise, trial.fit = noise1, fit1
            added += 1
        if added == 0:
            continue
        b = bic(ev, trial)
        assert trial.fit is not None and state.fit is not None
        mine = [c for c in state.candidates if c.effect == effect]
        chans = {i for c in mine for i in c.channels}
        helped = any(c in library and chans & set(c.channels) for c in state.candidates)
        if mimics(ev, K, mine, trial.candidates[-added:], th.alike_cosine) and (
            not helped or trial.fit.theta.size > state.fit.theta.size
        ):
            continue
        if b < current - th.tie_chi2 and (best is None or b < best[0]):
            best = (b, effect, trial)
    if best is None:
        return None
    b, effect, trial = best
    new = ", ".join(c.label for c in trial.candidates if c in library)
    notes[effect] = (
        f"entered first but {new} explains the recording better without it "
        f"(BIC {current:.1f} -> {b:.1f}): replaced"
    )
    trial.swapped.add(effect)
    return trial
