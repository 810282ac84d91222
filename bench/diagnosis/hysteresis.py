"""Memory of the last move: a bias that depends on the direction in which an axis last turned
(hysteresis of a flexure, a cable that drags, a fixture that settles against its last push).

No base quantity of the library expresses it, and it is no catalogue effect: the window's
pose is the same whichever way the table arrived. Its column for axis j on channel i is
s_wj on channel i, s_wj = +1 / −1 the sign of axis j's last non-zero move before window w
(``StaticEvidence.last_move_sign``), 0 before the axis first moved. It is tested against the
final model's residual with the final model's own window covariance C (the ``unexplained``
covariance): the GLS Wald statistic of the column added to the final design X,

    W = (cᵀ P y)² / (cᵀ P c),   P = C⁻¹ − C⁻¹X(XᵀC⁻¹X)⁻¹XᵀC⁻¹,

judged against F(1, n − p) at ``th.unexplained_alpha``, Bonferroni over the 3·k columns (every
channel and axis whose last-move sign takes both values). This is the fallback of the
``hysteresis`` candidate (``effects.last_move``) when the selection did not take it: the
column is not fitted, and ``unexplained`` says the remaining mismatch follows the
direction of the last move, on which channel and axis, and how large the bias step is.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import f as f_dist

from bench.diagnosis.effects import pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import window_covariance, without_pose
from bench.diagnosis.model_state import ModelState, design
from bench.diagnosis.refit import ModelFit
from bench.diagnosis.result import Unexplained
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds

CHANNELS = ("ax", "ay", "az")


@dataclass(frozen=True)
class LastMove:
    """The strongest dependence on the direction of the last move.

    :param axis: 0-based table axis; :param channel: 0, 1, 2.
    :param half_step: coefficient of s (channel units): the bias is ±half_step by direction.
    :param sigma: its one sigma; :param p_value: Bonferroni-corrected p.
    """

    axis: int
    channel: int
    half_step: float
    sigma: float
    p_value: float

    def sentence(self) -> str:
        """The ``unexplained`` text."""
        return (
            f"{CHANNELS[self.channel]} follows the direction of the last move of axis {self.axis + 1}: "
            f"the bias is {self.half_step:+.3g} ± {self.sigma:.2g} after a positive move and the opposite "
            f"after a negative one (p = {self.p_value:.2g}): memory of the last move (hysteresis), which "
            "no term of the model holds"
        )


def last_move_sign(
    q_rad: FloatArray, t_s: FloatArray, starts: list[int], th: Thresholds = THRESHOLDS
) -> FloatArray:
    """(m, k) sign of each axis's last move (faster than ``th.move_rate_deg_s``) before each
    window's first sample.

    :param q_rad: (n, k) unwrapped encoder angles; :param t_s: (n,) time (s);
    :param starts: first sample of each window.
    """
    rate = np.diff(q_rad, axis=0) / np.diff(t_s)[:, None]
    d = np.where(
        np.abs(rate) > np.deg2rad(th.move_rate_deg_s), np.sign(rate), 0.0
    )  # d[i]: from sample i to i + 1
    out = np.zeros((len(starts), q_rad.shape[1]))
    for j in range(q_rad.shape[1]):
        nz = np.flatnonzero(d[:, j])
        for w, s in enumerate(starts):
            k = np.searchsorted(nz, s, side="left") - 1  # last change ending at or before sample s
            out[w, j] = d[nz[k], j] if k >= 0 else 0.0
    return out


def last_move_test(
    ev: StaticEvidence,
    final: ModelFit,
    state: ModelState,
    K: FloatArray,
    fixed: FloatArray | None,
    th: Thresholds = THRESHOLDS,
) -> LastMove | None:
    """The strongest last-move column beside the final model, if it passes (module docstring)."""
    if ev.last_move_sign is None or not ev.orientation_known or state.noise is None:
        return None
    S = ev.last_move_sign
    axes = [j for j in range(S.shape[1]) if np.any(S[:, j] > 0) and np.any(S[:, j] < 0)]
    if not axes:
        return None
    cols, keys = [], []
    for j in axes:
        for i in range(3):
            c = np.zeros(ev.n_obs)
            c[i::3] = S[:, j]
            cols.append(c)
            keys.append((j, i))
    Cs = np.column_stack(cols)
    noise = state.noise if final.pose else without_pose(state.noise)
    fac = window_covariance(ev.V, ev.mid_s, noise, pose_response(ev, K), fixed).factor()
    X = design(ev, K, list(final.candidates))
    y = ev.y.reshape(-1)
    CiX, CiS = fac.solve(X), fac.solve(Cs)
    Pc = CiS - CiX @ np.linalg.solve(X.T @ CiX, X.T @ CiS)
    num = Pc.T @ y
    den = np.einsum("nq,nq->q", Cs, Pc)
    scale = np.einsum("nq,nq->q", Cs, CiS)
    W = np.where(den > 1e-9 * scale, num**2 / np.maximum(den, 1e-300), 0.0)  # a column in the model: 0
    best = int(np.argmax(W))
    dof = max(ev.n_obs - X.shape[1], 1)
    p = min(1.0, len(keys) * float(f_dist.sf(W[best], 1, dof)))
    if p >= th.unexplained_alpha:
        return None
    j, i = keys[best]
    return LastMove(
        axis=j, channel=i, half_step=float(num[best] / den[best]), sigma=float(den[best] ** -0.5), p_value=p
    )


def with_last_move(
    ev: StaticEvidence,
    final: ModelFit,
    state: ModelState,
    K: FloatArray,
    fixed: FloatArray | None,
    current: Unexplained | None,
    th: Thresholds = THRESHOLDS,
) -> Unexplained | None:
    """``current`` (the final model's ``unexplained``) with the last-move sentence when its test
    passes: the block is made if there was none, its ``where`` led by the sentence otherwise."""
    lm = last_move_test(ev, final, state, K, fixed, th)
    if lm is None:
        return current
    tag = f"direction of the last move of axis {lm.axis + 1} on {CHANNELS[lm.channel]}"
    test = f"last-move direction, GLS Wald beside the final model, F(1, n - p) at {th.unexplained_alpha:g}"
    if current is None:
        return Unexplained(
            chi2_dof=float(final.chi2_dof),
            test=test,
            p_value=lm.p_value,
            where=lm.sentence(),
            correlates_with=(tag,),
            channels={},
        )
    return replace(
        current,
        test=f"{current.test}; {test}",
        p_value=min(current.p_value, lm.p_value),
        where=f"{lm.sentence()}; {current.where}",
        correlates_with=(tag, *current.correlates_with),
    )
