"""Greedy forward selection of effects: a significance gate to admit, BIC to choose.

At each step every candidate not yet in the model is tried (fixed columns appended to the
design; the pose error as a variance component). A candidate is admitted only if

1. it is observable: its columns keep at least ``Thresholds.relative_leverage_min`` of their norm
   outside the span of the current design (else bias, K and the effects already in the
   model would absorb it: it is reported as indistinguishable, not guessed);
2. its statistic passes the gate at α = ``Thresholds.false_alarm`` / N (N candidates in the step).
   Fixed columns: LR = Δχ² = χ²_current − χ²_extended, both under the noise re-estimated
   (REML) under the extended model (the Wald statistic of the q new columns), must exceed
   q·F_{1−α}(q, n − p), p the extended design's columns (F rather than χ²_q because the
   noise level is estimated from the same n observations). The pose variance, a boundary
   parameter: LR = 2 Δℓ_REML against the 50:50 mixture of χ²_0 and χ²_1 (the χ²_1
   quantile at 2α);
3. its BIC change Δ = −LR + q ln n is negative (the pose error: the conditional BIC
   change given its angles, charged its effective degrees of freedom, ``catch_all``).

Each step tries the groups in order and takes the first with an admissible candidate:
the catalogue's columns; the library's terms beyond the catalogue (``library``; gate at
``Thresholds.library_share`` · α / N_L, ties among alike terms to the simplest); a swap of a catalogue
effect for library terms where that lowers the BIC (``_swap``); last the pose error, a
catch-all, which must also show the scatter its physics implies on every channel. Among
the admissible candidates of a group the one with the lowest BIC change enters; selection
stops when none is admissible. Candidates are ranked first with the current noise held
fixed and only the best ``Thresholds.shortlist`` are re-fitted with their own noise (the REML fit is
the expensive part).
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import chi2 as chi2_dist
from scipy.stats import f as f_dist

from bench.diagnosis.catch_all import pose_check
from bench.diagnosis.confounding import mimics
from bench.diagnosis.effects import Candidate, first_order_design, leverage, pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.greedy import NotedMove, Path, Trial, admits, extend, resume, step_alpha
from bench.diagnosis.likelihood import GlsFit, NoiseParams, window_covariance
from bench.diagnosis.model_state import (
    POSE_ERROR,
    ModelState,
    Step,
    bic,
    design,
    fit_model,
    lr_fixed,
    scale_matrix,
    whitened_lr,
)
from bench.diagnosis.refit import residual_dof
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.diagnosis.wander_cap import SlowNoiseCap
from bench.diagnosis.wander_modes import (
    WANDER_LIKE,
    follows_time,
    modulated_lr,
    modulated_note,
    pose_modulated,
    wander_note,
)

LIB = "discovered:"
"""Effect prefix of the library's terms (``library.EFFECT``)."""


def _structured(
    ev: StaticEvidence,
    pool: list[Candidate],
    state: ModelState,
    K: FloatArray,
    fixed: FloatArray | None,
    alpha: float,
    notes: dict[str, str],
    prescreen: float = 0.0,
    simplicity: dict[str, int] | None = None,
    cap: SlowNoiseCap | None = None,
    wander_notes: dict[str, str] | None = None,
    th: Thresholds = THRESHOLDS,
) -> tuple[float, Candidate, float, tuple[NoiseParams, GlsFit, FloatArray]] | None:
    """The best admissible fixed-column candidate of ``pool`` (gate at ``alpha`` each), or ``None``.

    ``prescreen`` (a fraction of the gate): candidates whose statistic under the current noise
    is below it are not re-fitted. ``simplicity`` (label -> degree): among admissible
    candidates within ``th.tie_chi2`` of the best (statistic under the windows' own scatter for
    the shortlist, then 2 ℓ_ML of the extended model under its own noise) the one of lowest
    degree is tried and enters. A drift or temperature claim (:data:`WANDER_LIKE`) must also
    beat the trend the measured wander makes: its statistic is the smaller of the one above and
    the likelihood ratio with each channel's own slow wander re-estimated in both models; so
    must a library term in time or temperature alone, and a pose-modulated library term in
    time or temperature must also pass the gate with the wander's leading mode (a trend) on
    its channel in the model (``wander_modes.modulated_lr``). Why such a claim was refused
    goes to ``notes`` (``wander_notes`` when given, the library's leverage notes being many).
    """
    assert state.noise is not None
    wander_notes = notes if wander_notes is None else wander_notes
    n = ev.n_obs
    X = design(ev, K, state.candidates)
    tried = [c for c in pool if c not in state.candidates]
    if not tried:
        return None
    cols = [c.columns(ev, K) for c in tried]
    rank_noise = state.noise
    if simplicity is not None:
        # rank the library against the windows' own scatter: a slow noise inflated by the very
        # mismatch a term would explain makes every term look alike
        rank_noise = replace(state.noise, tau2=np.zeros(3))
    lr0, lev = whitened_lr(ev, X, np.hstack(cols), rank_noise, K, fixed)
    ranked: list[tuple[float, Candidate]] = []
    col = 0
    Qx = np.linalg.qr(X)[0]  # one factor of the design for every candidate's leverage
    for cand, a in zip(tried, cols, strict=True):
        q = a.shape[1]
        lv = leverage(X, a, Qx)
        lev_min = th.relative_leverage_min
        if np.any(lv < lev_min) or np.any(lev[col : col + q] < lev_min):
            notes[cand.label] = (
                f"cannot be told apart from the model's other terms on this pose set "
                f"(only {float(np.min(lv)):.1e} of its signature is independent of them)"
            )
        elif q == 1:
            ranked.append((float(lr0[col]), cand))
        else:
            ranked.append((lr_fixed(ev, X, np.hstack([X, a]), state.noise, K, fixed), cand))
        col += q
    ranked.sort(key=lambda r: -r[0])
    if simplicity and len(ranked) > th.shortlist:
        # the simplest of the terms alike the best (within tie_chi2) is re-fitted too
        pos = {id(c): k for k, c in enumerate(tried)}
        Ap = np.hstack(cols)
        Ap = Ap - Qx @ (Qx.T @ Ap)
        Ap /= np.maximum(np.linalg.norm(Ap, axis=0), 1e-300)
        s_top = Ap[:, pos[id(ranked[0][1])]]
        near = [
            r
            for r in ranked
            if r[0] >= ranked[0][0] - th.tie_chi2
            and abs(float(Ap[:, pos[id(r[1])]] @ s_top)) > th.alike_cosine
        ]
        first = min(near, key=lambda r: (simplicity.get(r[1].label, 0), -r[0]))
        if first not in ranked[: th.shortlist]:
            ranked = [*ranked[: th.shortlist - 1], first]
    admissible = []
    null_own: tuple[NoiseParams, GlsFit, FloatArray] | None = None
    for lr_now, cand in ranked[: th.shortlist]:
        q = len(cand.names)
        gate = q * float(f_dist.ppf(1.0 - alpha, q, residual_dof(ev, X.shape[1] + q)))
        if lr_now < prescreen * gate:
            continue
        model1 = fit_model(ev, [*state.candidates, cand], state.pose, K, fixed, state.noise, cap=cap)
        noise1, _fit1, K1 = model1
        X1 = design(ev, K1, [*state.candidates, cand])
        lr = lr_fixed(ev, X1[:, : X.shape[1]], X1, noise1, K1, fixed)
        gate = q * float(f_dist.ppf(1.0 - alpha, q, residual_dof(ev, X1.shape[1])))
        term = cand.names[0] if cand.effect.startswith(LIB) else ""
        wander_like = cand.effect in WANDER_LIKE or (follows_time(term) and not pose_modulated(term))
        if term and follows_time(term) and pose_modulated(term) and lr > gate:
            C1 = window_covariance(ev.V, ev.mid_s, noise1, pose_response(ev, K1), fixed)
            lr_mod, b = modulated_lr(
                ev, X1[:, : X.shape[1]], X1[:, X.shape[1] :], cand.channels[0], C1, th.relative_leverage_min
            )
            gate_mod = q * float(f_dist.ppf(1.0 - alpha, q, residual_dof(ev, X1.shape[1] + b)))
            if lr_mod <= gate_mod:
                wander_notes[cand.label] = modulated_note(cand.label, lr, lr_mod, gate_mod)
                continue
        if wander_like and lr > gate:
            if null_own is None:
                null_own = fit_model(
                    ev, state.candidates, state.pose, K, fixed, state.noise, cap=cap, own=True
                )
            ext_own = fit_model(
                ev, [*state.candidates, cand], state.pose, K, fixed, null_own[0], cap=cap, own=True
            )
            lr_wander = max(0.0, 2.0 * (ext_own[1].loglik_ml - null_own[1].loglik_ml))
            if lr_wander <= gate:
                wander_notes[cand.label] = wander_note(cand.effect, lr, lr_wander, gate, null_own[0])
            lr = min(lr, lr_wander)
        dbic = -lr + q * math.log(n)
        if admits(Trial(cand, lr, gate, dbic)):
            admissible.append((dbic, cand, lr, model1))
    if not admissible:
        return None
    best = min(admissible, key=lambda a: a[0])
    if simplicity:
        # one column each: compare the extended models' own likelihoods (ML, each under its noise)
        top = max(admissible, key=lambda a: a[3][1].loglik_ml)

        def sig(c: Candidate) -> FloatArray:
            a = c.columns(ev, K)[:, 0]
            a = a - Qx @ (Qx.T @ a)
            return a / max(float(np.linalg.norm(a)), 1e-300)

        s_top = sig(top[1])
        alike = [
            a
            for a in admissible
            if 2.0 * (top[3][1].loglik_ml - a[3][1].loglik_ml) <= th.tie_chi2
            and abs(float(sig(a[1]) @ s_top)) > th.alike_cosine
        ]
        best = min(alike, key=lambda a: (simplicity.get(a[1].label, 0), -a[3][1].loglik_ml))
    else:
        # effects whose signatures coincide beyond the model and fit alike are a tie, not a
        # choice the data make: the one listed first in the pool (the catalogue's order) enters
        alike = [
            a
            for a in admissible
            if a[0] <= best[0] + th.tie_chi2 and same_signature(ev, K, X, a[1], best[1], th)
        ]
        best = min(alike, key=lambda a: tried.index(a[1]))
    return best


def same_signature(
    ev: StaticEvidence, K: FloatArray, X: FloatArray, a: Candidate, b: Candidate, th: Thresholds
) -> bool:
    """Whether every column of ``a`` lies in ``b``'s span beyond X, to |cos| > 1 − ``th.alias_tol``."""
    if a is b:
        return True
    Qx, _ = np.linalg.qr(X)
    A, B = a.columns(ev, K), b.columns(ev, K)
    A, B = A - Qx @ (Qx.T @ A), B - Qx @ (Qx.T @ B)
    Qb, _ = np.linalg.qr(B)
    na = np.maximum(np.linalg.norm(A, axis=0), 1e-300)
    return bool(np.all(np.linalg.norm(Qb.T @ A, axis=0) / na > 1.0 - th.alias_tol))


def _swap(
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
            step = _structured(
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


@dataclass(frozen=True)
class Selection:
    """A forward selection kept with its path (``greedy.Path``), so that a check after it (the
    catalogue's pruning, the out-of-sample referee) can take catalogue effects out of the pool
    and the selection resume without them (``greedy.resume``) instead of starting again.

    :param path: the models after each step and each step's notes.
    :param groups: the selection's groups of candidates, in the order they are asked.
    :param max_steps: most steps of the path.
    """

    path: Path[ModelState]
    groups: tuple[NotedMove[ModelState], ...]
    max_steps: int

    @property
    def model(self) -> ModelState:
        """A copy of the selected model (a check changes its copy; the path keeps its own)."""
        return self.path.last.copy()

    @property
    def notes(self) -> dict[str, str]:
        """Per candidate label, why it was not admitted (the steps of the path, in order)."""
        return self.path.noted

    def without(self, effects: Collection[str]) -> Selection:
        """The selection resumed from the step before the first of ``effects`` entered, with
        ``effects`` no longer candidates (``greedy.resume``). The steps before stand: each of
        ``effects`` was tried at them and lost, so their gates keep the share it took."""
        out = frozenset(effects)
        path = resume(
            self.path,
            self.groups,
            self.max_steps,
            holds=lambda s: any(c.effect in out for c in s.candidates),
            without=lambda s: replace(s.copy(), excluded=s.excluded | out),
        )
        return replace(self, path=path)


def select(
    ev: StaticEvidence,
    pool: list[Candidate],
    *,
    pose_allowed: bool,
    fixed: FloatArray | None = None,
    library: list[Candidate] | None = None,
    simplicity: dict[str, int] | None = None,
    excluded: Collection[str] = (),
    th: Thresholds = THRESHOLDS,
) -> Selection:
    """Run the greedy selection.

    Each step tries, in this order, and takes the first group with an admissible candidate:
    the catalogue's fixed columns (gate at ``th.false_alarm`` / N, N catalogue candidates plus
    the pose error); the library's terms (gate at ``th.library_share`` · ``th.false_alarm`` / N_L,
    N_L the library's size: a family that large must not spend the catalogue's budget);
    the pose error, a catch-all, last (its gate as the catalogue's, its BIC charged its
    effective degrees of freedom, and it must show the scatter its physics implies on every
    channel, ``catch_all``). A catalogue effect thus enters before a library term that
    would mimic it, and a structured term before a random effect that could absorb it.

    :param ev: the evidence.
    :param pool: observable catalogue candidates (fixed columns).
    :param pose_allowed: try the pose-error variance component.
    :param fixed: fixed extra covariance per window (orientation-free diagnosis).
    :param library: candidates beyond the catalogue (``library``), or ``None``.
    :param simplicity: library label -> degree, for ties (``_structured``).
    :param excluded: effects that are not candidates (withdrawn by a check before).
    :param th: the diagnosis's knobs (``thresholds``).
    :returns: the selection: its model, its path and, per candidate label, why it was not
        admitted when it could not be told from the model (``"indistinguishable"`` notes).
    """
    n = ev.n_obs
    state = ModelState(excluded=frozenset(excluded))
    X0 = first_order_design(ev.f_m_s2)
    K = np.asarray(np.linalg.lstsq(X0, ev.y.reshape(-1), rcond=None)[0][3:12], dtype=float).reshape(3, 3)
    cap = SlowNoiseCap(ev, th.cap_alpha)
    state.noise, state.fit, K = fit_model(ev, [], False, K, fixed, iterations=2, cap=cap)
    lib = library or []

    def in_pool(st: ModelState) -> list[Candidate]:
        # the catalogue's candidates: not swapped for library terms, not taken out by a check
        return [c for c in pool if c.effect not in st.swapped and c.effect not in st.excluded]

    def n_catalogue(st: ModelState) -> int:
        # the catalogue's candidates still to try, plus the pose error while it is not in
        pose_left = 1 if pose_allowed and not st.pose else 0
        return sum(1 for c in in_pool(st) if c not in st.candidates) + pose_left

    def admit(
        st: ModelState, step: tuple[float, Candidate, float, tuple[NoiseParams, GlsFit, FloatArray]]
    ) -> ModelState:
        dbic, chosen, lr, (noise1, fit1, _K1) = step
        return replace(
            st.copy(), candidates=[*st.candidates, chosen], noise=noise1, fit=fit1,
            steps=[*st.steps, Step(chosen.label, chosen.effect, lr, dbic, len(chosen.names))],
        )  # fmt: skip

    def catalogue(st: ModelState, notes: dict[str, str]) -> ModelState | None:
        alpha = step_alpha(th.false_alarm, n_catalogue(st))
        step = _structured(ev, in_pool(st), st, scale_matrix_of(st), fixed, alpha, notes, cap=cap, th=th)
        return None if step is None else admit(st, step)

    def beside(st: ModelState) -> list[Candidate]:
        # the library's terms and the catalogue effects searched with them, not taken out by a check
        return [c for c in lib if c.effect not in st.excluded]

    def beyond(st: ModelState, notes: dict[str, str]) -> ModelState | None:
        now = beside(st)
        n_lib = sum(1 for c in now if c not in st.candidates)
        step = _structured(
            ev, now, st, scale_matrix_of(st), fixed, th.library_share * step_alpha(th.false_alarm, n_lib), {},
            prescreen=th.prescreen, simplicity=simplicity, cap=cap, wander_notes=notes, th=th,
        )  # fmt: skip
        return None if step is None else admit(st, step)

    def swap(st: ModelState, notes: dict[str, str]) -> ModelState | None:
        return _swap(ev, st, scale_matrix_of(st), fixed, beside(st), notes, simplicity, cap, th)

    def pose(st: ModelState, notes: dict[str, str]) -> ModelState | None:
        return _pose_step(ev, st, fixed, step_alpha(th.false_alarm, n_catalogue(st)), notes, cap, n, th)

    groups = (catalogue, *((beyond, swap) if lib else ()), *((pose,) if pose_allowed else ()))
    return Selection(extend(Path.start(state), groups, th.max_steps), groups, th.max_steps)


def scale_matrix_of(state: ModelState) -> FloatArray:
    """K (3, 3) of the state's fit."""
    assert state.fit is not None
    return scale_matrix(state.fit)


def _pose_step(
    ev: StaticEvidence,
    state: ModelState,
    fixed: FloatArray | None,
    alpha: float,
    notes: dict[str, str],
    cap: SlowNoiseCap,
    n: int,
    th: Thresholds,
) -> ModelState | None:
    """The pose error, a catch-all variance component, as the selection's last group (``select``)."""
    assert state.noise is not None and state.fit is not None
    if state.pose:
        return None
    noise1, fit1, K1 = fit_model(
        ev, state.candidates, True, scale_matrix_of(state), fixed, state.noise, cap=cap
    )
    if noise1.pose_var_rad2 <= 0:
        return None
    lr = 2.0 * (fit1.loglik_reml - state.fit.loglik_reml)
    if lr <= float(chi2_dist.ppf(1.0 - 2.0 * alpha, 1)):
        return None
    chk = pose_check(
        ev.V,
        ev.mid_s,
        noise1,
        pose_response(ev, K1),
        design(ev, K1, state.candidates),
        ev.y.reshape(-1),
        fixed,
        th,
    )
    gain = 2.0 * (chk.loglik_conditional - state.fit.loglik_ml)
    dbic = -gain + max(chk.edf, 1.0) * math.log(n)
    if dbic >= 0:
        notes["pose_error"] = (
            f"a random pose error would raise the likelihood given its angles by {gain:.1f} (2 dl) "
            f"but spends {chk.edf:.1f} effective degrees of freedom: BIC change {dbic:+.1f}; not claimed"
        )
        return None
    if not chk.consistent:
        notes["pose_error"] = chk.text()
        return None
    return replace(
        state.copy(), pose=True, pose_edf=chk.edf, noise=noise1, fit=fit1,
        steps=[*state.steps, Step(POSE_ERROR, POSE_ERROR, lr, dbic, 1)],
    )  # fmt: skip
