"""What no prediction of a design can go below, in closed form, and the targets it rules out.

The planner (``bench.planning.search``) passes over a design whose :func:`floor` already misses
a target, and over every design of the same dwell with fewer passes (the floors only rise as the
passes fall), without evaluating it; and when no design meets the targets it evaluates a dwell's
longest design for the closest one only while its floor is below the closest found so far.
Neither changes the plan: a prediction is never below its floor (``tests/bench/planning``).
"""

from __future__ import annotations

from dataclasses import dataclass

from bench.planning.evaluation import Targets
from bench.planning.every_sample import BLOCK_S
from bench.planning.information import wander_bound_bias, white_bound_bias, white_bound_k
from bench.planning.noise import UnitNoise

BOUND_MARGIN = 1e-6
"""Relative margin by which a floor must miss a target before a design is passed over
unevaluated (rounding never decides it)."""


@dataclass(frozen=True)
class Floor:
    """Standard uncertainties (k = 1) a design's prediction cannot go below (:func:`floor`).

    :param k: σ(K_ij): of the RMS over the nine elements, of the largest scale factor and of the
        largest misalignment alike.
    :param bias_m_s2: σ(b_i) of the largest bias (m/s²).
    """

    k: float
    bias_m_s2: float

    def misses(self, targets: Targets) -> bool:
        """Some target is below what the floor allows at k = 2."""
        pairs = (
            (targets.bias_m_s2, self.bias_m_s2),
            (targets.scale, self.k),
            (targets.misalignment_rad, self.k),
        )
        return any(t is not None and 2.0 * s > t for t, s in pairs)


def floor(noise: UnitNoise, info_s: float, span_s: float, g_m_s2: float) -> Floor:
    """What no prediction of a design whose fit weighs at most ``info_s`` seconds of record
    spanning at most ``span_s`` seconds can go below, less :data:`BOUND_MARGIN`.

    The predicted covariance is at least its white part (the slow noise adds a positive
    kernel): for the every-sample fit N²f_s·A⁻¹, A = Σ_t x_t x_tᵀ over n = f_s·info_s samples;
    for the window fit (Σ_w (T_w/N²)·H_wᵀH_w)⁻¹, info_s = Σ_w T_w. [A⁻¹]_jj ≥ 1/A_jj, and with
    |f| = g the K columns' A_jj sum to g²·info_s/N² (in units of the white density), so for
    every channel i Σ_j σ²(K_ij) ≥ 9N²/(g²·info_s): the RMS σ(K_ij) is at least √3·N/(g·√info_s),
    and at the least-covered direction j so are the scale σ(K_jj) and the misalignments
    σ(K_ij); σ(b_i) ≥ N/√info_s (``information.white_bound_k``, ``white_bound_bias``). The bias
    is also at least the wander's bound over the span (``information.wander_bound_bias``).
    Both floors fall as info_s and span_s grow: a design with fewer passes has a higher one.
    """
    n = noise.white_m_s2_rt_hz
    k = white_bound_k(n, info_s, g_m_s2)
    b = max(white_bound_bias(n, info_s), wander_bound_bias(noise.wander_m_s2, noise.wander_tau_s, span_s))
    return Floor(k * (1.0 - BOUND_MARGIN), b * (1.0 - BOUND_MARGIN))


def cannot_meet(targets: Targets, noise: UnitNoise, span_s: float, g_m_s2: float) -> bool:
    """Whether no every-sample prediction over ``span_s`` seconds of samples can meet ``targets``
    (:func:`floor`; its 1-s blocks of slow noise span at most ``span_s`` + 1 s)."""
    return floor(noise, span_s, span_s + BLOCK_S, g_m_s2).misses(targets)
