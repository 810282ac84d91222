"""Catalogue first, but not by default: a moving recording's catalogue path cut short where the
library explains the recording better without the catalogue's later steps.

The dynamic selection (``dynamic.select_terms``) is greedy: a mismatch the catalogue cannot
express (one channel delayed behind the others) is first absorbed, in part, by the effects
that come closest (a common time skew, then a lever arm and proof masses that mop up what the
skew leaves), and the library then finds the rest. For each k = 0 … K − 1 (K catalogue steps
taken) the library is searched again after the first k steps only
(``library_motion_search``, its gates unchanged; the catalogue terms dropped are then among
those whose span marks a library term as the catalogue's, so no term they could mimic can
replace them). To keep the cost at two searches, the full path's terms are first refitted
after each shorter path and only the best of those is searched again. The model of lowest
BIC, n Σ_c ln σ̂²_c + p ln(3n) with p counting every coefficient, wins; a shorter catalogue
path only on "strong" evidence, a BIC lower by more than ``Thresholds.tie_chi2`` (Kass & Raftery, JASA
90 (1995) 773), as the static library's swap. The cut is tried only when the full path's
search discovered a term (the case where a catalogue step may have taken part of it).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bench.diagnosis.library_motion_search import MotionLibraryResult
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit

FloatArray = np.ndarray
Search = Callable[[int], tuple[MotionLibraryResult, dict[str, FloatArray]]]
Rescore = Callable[[int, MotionLibraryResult, dict[str, FloatArray]], float]


def fit_bic(fit: DynamicFit, n_library: int) -> float:
    """n Σ_c ln σ̂²_c + p ln(3n) of a fit with ``n_library`` library coefficients beside its own."""
    p = fit.spec.n_params + n_library
    return float(fit.n_used * np.sum(np.log(fit.noise_sigma**2)) + p * math.log(3 * fit.n_used))


def model_bic(lib: MotionLibraryResult) -> float:
    """:func:`fit_bic` of the final model of a search (catalogue and library coefficients)."""
    return fit_bic(lib.fits[-1], len(lib.included))


def cut_catalogue(
    search: Search,
    rescore: Rescore,
    n_steps: int,
    chosen: tuple[str, ...],
    th: Thresholds = THRESHOLDS,
) -> tuple[int, MotionLibraryResult, dict[str, FloatArray], str | None]:
    """(k, the search after the first k catalogue steps, its base values, a note) (module docstring).

    The full path's library terms are refitted after each shorter path first (``rescore``,
    cheap); the library is searched again only after the shortest path whose BIC is lowest,
    and that search's model must itself beat the full one.

    :param search: k -> the library search after the first k of the catalogue's steps.
    :param rescore: (k, the full path's search, its base values) -> BIC of the first k steps
        with its terms refitted.
    :param n_steps: the catalogue's steps taken; :param chosen: their terms, in order.
    """
    lib, vals = search(n_steps)
    if not lib.included or n_steps == 0:
        return n_steps, lib, vals, None
    full = model_bic(lib)
    scores = {k: rescore(k, lib, vals) for k in range(n_steps)}
    k = min(scores, key=lambda j: (scores[j], j))
    if scores[k] >= full - th.tie_chi2:
        return n_steps, lib, vals, None
    lk, vk = search(k)
    b = model_bic(lk)
    if not lk.included or b >= full - th.tie_chi2:
        return n_steps, lib, vals, None
    new = ", ".join(i.term.label for i in lk.included)
    note = (
        f"{', '.join(chosen[k:])}: entered first but {new} explains the recording better without "
        f"{'it' if n_steps - k == 1 else 'them'} (BIC {full:.1f} -> {b:.1f}): replaced"
    )
    return k, lk, vk, note
