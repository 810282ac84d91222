"""What a diagnosis says of its claims beside the model: which effects and library terms fit
the recording about as well (|cos| of their signatures beyond the first-order model above
``Thresholds.confound_cosine``), why two effects cannot be told apart, and a discovered term's report
(coefficient and sigma in channel units per unit of the term, ΔBIC, residual after, the
physics sentence of ``library.physics``; ``docs/cli-contract.md``, "Beyond the catalogue")."""

from __future__ import annotations

import numpy as np

from bench.diagnosis.effects import Candidate
from bench.diagnosis.effects.base import FloatArray, first_order_design
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.library import EFFECT, LibraryTerm, physics
from bench.diagnosis.library import candidate as library_candidate
from bench.diagnosis.model_state import ModelState
from bench.diagnosis.refit import ModelFit, effect_parameters
from bench.diagnosis.residuals import CHANNELS
from bench.diagnosis.result import Discovery
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


def confounded(
    ev: StaticEvidence,
    K: FloatArray,
    chosen: list[Candidate],
    pool: list[Candidate],
    th: Thresholds = THRESHOLDS,
) -> dict[str, dict[str, float]]:
    """Per chosen effect, the pool's effects whose signatures lie within
    ``th.confound_cosine`` of its own (|cos| beyond the first-order model)."""
    X0 = first_order_design(ev.f_m_s2)
    Q, _ = np.linalg.qr(X0)

    def sig(c: Candidate) -> FloatArray:
        a = c.columns(ev, K)
        a = a - Q @ (Q.T @ a)
        n = np.linalg.norm(a, axis=0)
        return a / np.where(n > 0, n, 1.0)

    out: dict[str, dict[str, float]] = {}
    for c in chosen:
        sc = sig(c)
        for d in pool:
            if d.effect == c.effect or d in chosen or d.family is not None:
                # a family (a lag's τ still free) has no one signature; where it was resolved
                # its fixed candidate is what the model holds, and at τ → 0 it is the effect it
                # reduces to, which the selection already weighed (``profiled.resolve``)
                continue
            cos = float(np.max(np.abs(sc.T @ sig(d))))
            if cos > th.confound_cosine:
                prev = out.setdefault(c.effect, {}).get(d.effect, 0.0)
                out[c.effect][d.effect] = max(prev, cos)
    return out


def why(ev: StaticEvidence, a: str, b: str) -> str:
    if {a, b} == {"temperature_bias", "bias_drift"} and ev.temp_c is not None:
        r = float(np.corrcoef(ev.temp_c, ev.mid_s)[0, 1])
        return (
            f": the temperature follows time, r = {r:.2f} between the windows' temperature and time; "
            "vary the temperature independently of time to separate them"
        )
    return ""


def discovery(
    ev: StaticEvidence,
    t: LibraryTerm,
    final: ModelFit,
    seq: list[ModelFit],
    k: int,
    K: FloatArray,
    state: ModelState,
    channel_unit: str,
    lib_terms: dict[str, LibraryTerm],
    pool: list[Candidate],
    th: Thresholds = THRESHOLDS,
) -> Discovery:
    """The contract entry of one library term in the final model."""
    key = f"{EFFECT}:{t.label}"
    params, sigma = effect_parameters(final, key, K)
    X0 = first_order_design(ev.f_m_s2)
    Q, _ = np.linalg.qr(X0)
    mine = library_candidate(t).columns(ev, K)[:, 0]
    mine = mine - Q @ (Q.T @ mine)
    mine /= np.linalg.norm(mine)
    alike: list[tuple[float, str]] = []
    for other_key, other in lib_terms.items():
        if other_key == key or other.channel != t.channel:
            continue
        a = library_candidate(other).columns(ev, K)[:, 0]
        a = a - Q @ (Q.T @ a)
        cos = abs(float(mine @ a)) / max(float(np.linalg.norm(a)), 1e-300)
        if cos > th.confound_cosine:
            alike.append((cos, other.term))
    for c in pool:
        if t.channel not in c.channels or c.family is not None:
            continue
        a = c.columns(ev, K)
        a = a - Q @ (Q.T @ a)
        nrm = np.linalg.norm(a, axis=0)
        cos = float(np.max(np.abs(mine @ a) / np.maximum(nrm, 1e-300)))
        if cos > th.confound_cosine:
            alike.append((cos, c.label))
    alike.sort(reverse=True)
    text = physics(t)
    if t.aliases:
        text += f"; on this pose set it is the same signature as {', '.join(t.aliases)}"
    if alike:
        text += "; it fits this recording about as well as " + ", ".join(
            f"{name} (|cos| = {cos:.2f})" for cos, name in alike[:4]
        )
    step = next(s for s in state.steps if s.effect == key)
    coefficient, coefficient_sigma = params["coefficient"], sigma["coefficient"]
    if not isinstance(coefficient, float) or not isinstance(coefficient_sigma, float):
        raise TypeError(f"effect {key!r}: its contract coefficient and sigma are not numbers")
    return Discovery(
        channel=CHANNELS[t.channel],
        term=t.term,
        coefficient=coefficient,
        sigma=coefficient_sigma,
        unit=f"{channel_unit or 'channel unit'} per {t.unit}",
        delta_bic=float(seq[k + 1].bic - seq[k].bic),
        residual_rms_after=float(np.sqrt(np.mean(seq[k + 1].resid ** 2))),
        physics=text,
        lr=float(step.lr),
        confounded_with=tuple(name for _, name in alike[:4]),
    )


def mimics(
    ev: StaticEvidence, K: FloatArray, effect: list[Candidate], terms: list[Candidate], cosine: float
) -> bool:
    """Whether the catalogue effect's columns can mimic one of the library terms: beyond the
    first-order model, the term's signature lies within ``cosine`` of their span."""
    X0 = first_order_design(ev.f_m_s2)
    Q0, _ = np.linalg.qr(X0)
    E = np.hstack([c.columns(ev, K) for c in effect])
    E = E - Q0 @ (Q0.T @ E)
    Qe, _ = np.linalg.qr(E)
    for t in terms:
        a = t.columns(ev, K)[:, 0]
        a = a - Q0 @ (Q0.T @ a)
        na = float(np.linalg.norm(a))
        if na > 0 and float(np.linalg.norm(Qe.T @ a)) / na > cosine:
            return True
    return False
