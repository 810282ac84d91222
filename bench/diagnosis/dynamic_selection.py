"""The moving recording's term selection: which dynamic-model terms the motion determines
(:func:`screen_terms`), the greedy selection over them on the selection core (``greedy``,
:func:`forward_terms`) and the claim the selection and the moving library make together
(:class:`CatalogueClaim`). The stages that run them are in ``moving_stages``; the selection's
statistics: ``dynamic`` module docstring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.greedy import Trial, best, forward, step_alpha
from bench.diagnosis.library_motion_search import MotionLibraryResult
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit, fit_dynamic_batch, linear_start, white_sigma
from bench.estimation.dynamic_model import TERM_ORDER, ModelSpec, initial_theta
from bench.estimation.motion_data import MotionData
from bench.estimation.observability import fisher_information, information_report

FloatArray = np.ndarray


def departure(fit: DynamicFit, term: str, lever: FloatArray) -> tuple[FloatArray, FloatArray, int]:
    """(δ, Cov δ, dof) of the module docstring.

    Once the proof masses are in, the lever arm is their mean position r = (q_x + q_y + q_z)/3.
    """
    if term == "lever_arm" and "lever_arm" not in fit.spec.terms:
        s = fit.spec.index("proof_mass_offsets")
        A = np.tile(np.eye(3) / 3.0, (1, 3))
        return A @ fit.theta[s] - lever, A @ fit.cov[s, s] @ A.T, 3
    s = fit.spec.index(term)
    th, C = fit.theta[s], fit.cov[s, s]
    if term == "lever_arm":
        return th - lever, C, 3
    if term == "proof_mass_offsets":
        T = np.eye(9) - np.tile(np.tile(np.eye(3) / 3.0, (1, 3)), (3, 1))
        return T @ th, T @ C @ T.T, 6
    return th, C, th.size


def _wald(d: FloatArray, C: FloatArray, q: int) -> float:
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    keep = np.argsort(w)[::-1][:q]
    u = V[:, keep].T @ d
    return float(np.sum(u * u / np.maximum(w[keep], 1e-300)))


def _loglik_term(fit: DynamicFit) -> float:
    return float(fit.n_used * np.sum(np.log(fit.noise_sigma**2)))


@dataclass(frozen=True)
class TermSelection:
    """The greedy forward selection of the dynamic model's terms (module docstring).

    :param candidates: terms the motion determines, tried in turn.
    :param unobservable: term -> why the motion cannot determine it.
    :param steps: (term, ΔBIC, Wald W) of each term admitted, in order.
    :param fits: the baseline fit, then the fit after each step (``fits[-1]`` is the final model).
    :param rejected: term -> why it did not enter (its statistics at the last step).
    :param false_alarm: false-alarm probability of one step.
    """

    candidates: tuple[str, ...]
    unobservable: dict[str, str]
    steps: tuple[tuple[str, float, float], ...]
    fits: tuple[DynamicFit, ...]
    rejected: dict[str, str]
    false_alarm: float

    @property
    def chosen(self) -> tuple[str, ...]:
        """The admitted terms, in order."""
        return tuple(t for t, _, _ in self.steps)


def _warm_start(fit: DynamicFit, spec: ModelSpec, lever: FloatArray) -> FloatArray:
    """Start of an extended model at the current fit: its parameters kept, the new term at
    the believed geometry (the proof masses at the fitted lever arm)."""
    th = fit.theta
    r = th[fit.spec.index("lever_arm")] if "lever_arm" in fit.spec.terms else lever
    out = initial_theta(spec, th[:3], th[3:12].reshape(3, 3), r)
    for t in fit.spec.terms:
        if t in spec.terms:
            out[spec.index(t)] = th[fit.spec.index(t)]
    return out


def screen_terms(
    m: MotionData, y: FloatArray, g_m_s2: float, lever: FloatArray
) -> tuple[tuple[str, ...], dict[str, str]]:
    """(the terms the motion determines, term -> why the others are not): the Fisher
    information of each term's extended model at the linear start must be of full rank
    (``observability.information_report``).

    :raises ValueError: a motion that cannot determine bias and K.
    """
    sig_w = np.maximum(white_sigma(y[m.valid]), 1e-12)
    b0, K0 = linear_start(m, y, g_m_s2, lever)
    unobservable: dict[str, str] = {}
    pool = []
    for t in TERM_ORDER:
        spec = ModelSpec(("lever_arm", t)) if t == "proof_mass_offsets" else ModelSpec((t,))
        rep = information_report(
            fisher_information(m, initial_theta(spec, b0, K0, lever), spec, g_m_s2, lever, sig_w), spec.names
        )
        if rep.ok:
            pool.append(t)
        else:
            unobservable[t] = "not determined by this motion: " + "; ".join(rep.unobservable)
    return tuple(pool), unobservable


def forward_terms(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever: FloatArray,
    pool: tuple[str, ...],
    unobservable: dict[str, str],
    th: Thresholds = THRESHOLDS,
) -> TermSelection:
    """Greedy forward selection over ``pool`` on the selection core (``greedy.forward``, module
    docstring of ``dynamic``)."""
    n_obs = 3 * int(m.valid.sum())
    fits = [fit_dynamic_batch(m, y, g_m_s2, lever, ModelSpec(()))]
    chosen: list[str] = []
    steps: list[tuple[str, float, float]] = []
    rejected: dict[str, str] = {}

    def catalogue(n_steps: int) -> int | None:
        tried = [t for t in pool if t not in chosen and (t != "proof_mass_offsets" or "lever_arm" in chosen)]
        if not tried:
            return None
        alpha = step_alpha(th.false_alarm, len(tried))
        trials: list[Trial[tuple[str, DynamicFit]]] = []
        rejected.clear()
        for t in tried:
            spec1 = ModelSpec((*chosen, t))
            try:
                f1 = fit_dynamic_batch(m, y, g_m_s2, lever, spec1, theta0=_warm_start(fits[-1], spec1, lever))
            except ValueError as exc:
                rejected[t] = f"the fit with it failed: {exc}"
                continue
            d, C, q = departure(f1, t, lever)
            w = _wald(d, C, q)
            crit = float(chi2_dist.ppf(1.0 - alpha, q))
            dbic = _loglik_term(f1) - _loglik_term(fits[-1]) + q * math.log(n_obs)
            trials.append(Trial((t, f1), w, crit, dbic))
            rejected[t] = (
                f"no evidence on this recording: Wald W = {w:.3g} against {crit:.3g} (chi2_{q} at "
                f"{alpha:.2g}), delta BIC {dbic:+.3g}"
            )
        win = best(trials)
        if win is None:
            return None
        t, f1 = win.item
        chosen.append(t)
        steps.append((t, win.delta_bic, win.statistic))
        fits.append(f1)
        rejected.pop(t, None)
        return n_steps + 1

    forward(0, [catalogue], len(pool))
    for t in pool:
        if t not in chosen and t not in rejected:
            rejected[t] = "tried only with lever_arm in the model (its offsets are relative to it)"
    return TermSelection(
        candidates=tuple(pool),
        unobservable=unobservable,
        steps=tuple(steps),
        fits=tuple(fits),
        rejected=rejected,
        false_alarm=th.false_alarm,
    )


def select_terms(
    m: MotionData, y: FloatArray, g_m_s2: float, lever: FloatArray, *, th: Thresholds = THRESHOLDS
) -> TermSelection:
    """Greedy forward selection of the terms the recording supports: :func:`screen_terms`, then
    :func:`forward_terms`.

    :param m: the motion; :param y: (n, 3) raw samples; :param lever: (3,) believed lever arm (m).
    :raises ValueError: a motion that cannot determine bias and K.
    """
    pool, unobservable = screen_terms(m, y, g_m_s2, lever)
    return forward_terms(m, y, g_m_s2, lever, pool, unobservable, th)


@dataclass(frozen=True)
class CatalogueClaim:
    """The catalogue terms a moving recording's diagnosis claims, shared with ``calibrate``.

    :param selection: the greedy catalogue selection (``select_terms``).
    :param k: how many of its steps are claimed: the first k (the later ones replaced by
        library terms that explain the recording better without them, ``cut_catalogue``).
    :param library: the library search after those k steps; :param values: its base values.
    :param note: why steps were replaced, or ``None``.
    """

    selection: TermSelection
    k: int
    library: MotionLibraryResult
    values: dict[str, FloatArray]
    note: str | None

    @property
    def terms(self) -> tuple[str, ...]:
        """The claimed catalogue terms, in order."""
        return self.selection.chosen[: self.k]

    @property
    def fit(self) -> DynamicFit:
        """The catalogue model of the claimed terms."""
        return self.selection.fits[self.k]

    @property
    def fits(self) -> tuple[DynamicFit, ...]:
        """The baseline fit, then the fit after each claimed step and each library term;
        ``fits[-1]`` is the final model."""
        return (*self.selection.fits[: self.k + 1], *self.library.fits[1:])

    def fit_of(self, terms: tuple[str, ...]) -> DynamicFit | None:
        """The catalogue model of ``terms`` when they are the selection's first steps, else ``None``."""
        k = len(terms)
        return self.selection.fits[k] if self.selection.chosen[:k] == terms else None

    @property
    def library_signal(self) -> FloatArray | None:
        """(n, 3) the discovered terms' contribution Σ c_k x_k (channel units), or ``None``
        when the library discovered nothing."""
        return self.library.adjustment(self.values) if self.library.included else None


def catalogue_span(sel: TermSelection, lever: FloatArray, k: int) -> tuple[ModelSpec, FloatArray] | None:
    """The catalogue's observable terms together at the fit after its first k steps (the others at
    their null): a library term inside their span beyond the model is the catalogue's
    (``library_motion``)."""
    final = sel.fits[k]
    kept = sel.chosen[:k]
    spec = ModelSpec((*kept, *(t for t in sel.candidates if t not in kept)))
    if spec.terms == final.spec.terms:
        return None
    return spec, _warm_start(final, spec, lever)
