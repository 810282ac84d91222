"""Whether one channel carries a misfit the shared slow noise hides: a likelihood-ratio test.

The noise model's slow wander is one input-referred level shared by the three channels
(``likelihood``: τ_i² = λ s_i, s_i the channel's share from its gain). A mismatch on one
channel alone (a connector that re-seats at each move, a term the model lacks on that
channel) raises λ until that channel looks fine, and the other two channels then sit far
below what λ implies: their χ² over its expectation falls to a few per cent. The per-channel
and channel-against-channel χ² tests of ``unexplained`` lose their power there, because
under the inflated, long-correlated wander each channel's χ² has only a few effective
degrees of freedom.

The test here asks the likelihood directly. Under the final model (design X, window noise
B_w, correlation time T_c and pose variance as fitted) compare

    H0:   C = blockdiag(B_w + κ S) + λ (s ⊗ P),                   λ, κ ≥ 0 re-estimated,
    H1_i: C = blockdiag(B_w + κ S + ε_i² e_i e_iᵀ) + λ (s ⊗ P),   λ, κ, ε_i² ≥ 0 re-estimated,

S = diag(s). κ S is a misfit common to the channels (input-referred, independent from window
to window: what the model lacks on every channel alike, e.g. each reading's magnitude off by
a random amount); ε_i² is an excess on channel i alone, independent from window to window
(what a one-channel mismatch looks like once the model has taken what it can). Without κ
in H0 a misfit common to the channels would be named on whichever channel fits it best.
Both by REML (Harville, JASA 72 (1977) 320; ``slow_noise``), λ bounded by the windows' own
half-window differences in both (``wander_cap``: the shared level may not exceed what the
tightest channel's samples allow). The statistic LR_i = 2 (ℓ_REML(H1_i) − ℓ_REML(H0)) tests
one variance component on the boundary of its space: asymptotically ½ χ²_0 + ½ χ²_1 (Self &
Liang, JASA 82 (1987) 605, case 5; Stram & Lee, Biometrics 50 (1994) 1171), so
p_i = ½ P(χ²_1 > LR_i) for LR_i > 0. The largest of the three is judged with a Bonferroni
factor 3. Its level on a few dozen window means is checked by simulation
(``tests/bench/diagnosis/test_channel_excess.py``, ``benchmarks/study_diagnose_one_channel``).

Each likelihood is maximised by bounded Powell searches over the logs of the variances (two
starts each: the other hypothesis's optimum, and the misfit moved between the components),
about 900 GLS evaluations of O(m) each (``window_covariance``).

Limit: the model's wander is one level for all channels. A unit whose channels wander by
different amounts (input-referred) shows the noisier channel as an excess here; the finding
then says that channel's scatter between windows is beyond what the others' allow, which is
what the recording shows.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
from scipy.optimize import minimize
from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import NoiseParams, gls, window_covariance
from bench.diagnosis.wander_cap import SlowNoiseCap
from bench.estimation.warm_search import memoised
from bench.estimation.window_covariance import WindowCovariance, invert_blocks


@dataclass(frozen=True)
class ChannelExcess:
    """The test of the module docstring.

    :param lr: (3,) LR_i per channel (≥ 0).
    :param excess_var: (3,) ε̂_i² under H1_i (channel units²).
    :param channel: the channel with the largest LR (0, 1, 2).
    :param p_value: min(1, 3 · ½ P(χ²_1 > LR_max)) (1 when LR_max = 0).
    :param shared_tau2: (3,) τ_i² = λ̂ s_i under H0 (channel units²).
    :param common_var: (3,) κ̂ s_i, the excess common to the channels under H0 (channel units²).
    """

    lr: FloatArray
    excess_var: FloatArray
    channel: int
    p_value: float
    shared_tau2: FloatArray
    common_var: FloatArray


def _powell(
    fun: Callable[[FloatArray], float],
    starts: Sequence[tuple[float, ...]],
    bounds: list[tuple[float, float]],
) -> tuple[float, FloatArray]:
    """(min, argmin) of ``fun`` within ``bounds``: bounded Powell from each start, the best kept."""
    lo, hi = np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])
    best: tuple[float, FloatArray] | None = None
    for s in starts:
        x0 = np.clip(np.array(s, dtype=float), lo, hi)
        try:
            r = minimize(fun, x0, method="Powell", bounds=bounds, options={"xtol": 0.1, "ftol": 1e-4})
            val, x = float(r.fun), np.asarray(r.x, dtype=float)
        except ValueError:  # scipy's bounded Powell can fail in its extrapolation step
            val, x = fun(x0), x0
        if best is None or val < best[0]:
            best = (val, x)
    assert best is not None
    return best


@dataclass(frozen=True)
class ExcessModel:
    """The covariances of the module docstring's hypotheses for one recording and noise.

    A point is x = (log λ, log κ[, log ε_i²]) relative to ``scale`` (channel units²); a log at
    or below ``LOG_NONE`` (a numerical floor, e⁻³⁰ of the window noise) is no variance at all.

    :param base: the window covariance without wander (T_c and the pose variance as fitted).
    :param shape: (3,) s_i, the channels' shares of an input-referred variance.
    :param scale: the median window variance (channel units²).
    :param u_hi: the upper bound of log λ (the slow-noise cap, ``wander_cap``).
    """

    LOG_NONE: ClassVar[float] = -30.0

    base: WindowCovariance
    shape: FloatArray
    scale: float
    u_hi: float

    @classmethod
    def build(
        cls,
        ev: StaticEvidence,
        noise: NoiseParams,
        J_pose: FloatArray | None,
        fixed: FloatArray | None,
        cap: SlowNoiseCap | None,
    ) -> ExcessModel:
        """The model of ``channel_excess``'s arguments."""
        vdiag = np.diagonal(ev.V, axis1=1, axis2=2)
        gain2 = np.median(vdiag, axis=0)
        shape = gain2 / float(np.mean(gain2))
        scale = float(np.median(vdiag))
        base = window_covariance(ev.V, ev.mid_s, replace(noise, tau2=np.zeros(3)), J_pose, fixed)
        tc = float(noise.corr_time_s)
        u_hi = 12.0
        bound = cap(tc) if cap is not None and tc > 0 else None
        if bound is not None:
            u_hi = float(
                np.clip(np.log(np.maximum(np.min(bound / shape), 1e-300) / scale), cls.LOG_NONE, 12.0)
            )
        return cls(base=base, shape=shape, scale=scale, u_hi=u_hi)

    def size(self, u: float) -> float:
        """The variance (channel units²) of log u."""
        return 0.0 if u <= self.LOG_NONE + 1e-6 else self.scale * float(np.exp(u))

    def covariance(self, x: FloatArray, channel: int | None) -> WindowCovariance:
        """C at x, the excess ε² (x[2]) on ``channel`` (none when ``channel`` is ``None``)."""
        blocks = self.base.blocks + self.size(float(x[1])) * np.diag(self.shape)
        if channel is not None:
            blocks = blocks.copy()
            blocks[:, channel, channel] += self.size(float(x[2]))
        inv, logdet = invert_blocks(blocks)
        return replace(
            self.base,
            blocks=blocks,
            tau2=self.size(float(x[0])) * self.shape,
            blocks_inverse=inv,
            blocks_logdet=logdet,
        )

    def neg_reml(self, X: FloatArray, z: FloatArray, x: FloatArray, channel: int | None) -> float:
        """−ℓ_REML of z on X at x (1e300 where C or X cannot be factored)."""
        try:
            return -gls(X, z, self.covariance(x, channel)).loglik_reml
        except ValueError:
            return 1e300

    def fit_shared(self, X: FloatArray, z: FloatArray) -> tuple[float, FloatArray]:
        """(−ℓ_REML, x̂) of H0: λ and κ re-estimated."""
        return _powell(
            memoised(lambda x: self.neg_reml(X, z, x, None)),
            [(self.u_hi - 4.0, self.LOG_NONE), (self.LOG_NONE, 0.0)],
            [(self.LOG_NONE, self.u_hi), (self.LOG_NONE, 12.0)],
        )

    def fit_channel(
        self, X: FloatArray, z: FloatArray, channel: int, x0: FloatArray
    ) -> tuple[float, FloatArray]:
        """(−ℓ_REML, x̂) of H1_i on ``channel``: λ, κ and ε_i² re-estimated; x0 is H0's optimum
        (starts: it with no excess, and the misfit moved to channel i alone)."""
        starts = [(x0[0], x0[1], self.LOG_NONE), (x0[0] - 4.0, x0[1] - 4.0, 0.0)]
        return _powell(
            memoised(lambda x: self.neg_reml(X, z, x, channel)),
            starts,
            [(self.LOG_NONE, self.u_hi), (self.LOG_NONE, 12.0), (self.LOG_NONE, 12.0)],
        )


def channel_excess(
    ev: StaticEvidence,
    X: FloatArray,
    noise: NoiseParams,
    J_pose: FloatArray | None,
    fixed: FloatArray | None,
    cap: SlowNoiseCap | None,
) -> ChannelExcess:
    """LR_i of the module docstring for the final model.

    :param X: (3m, p) the final design; :param noise: the final noise (T_c and the pose
        variance are kept, λ re-estimated); :param J_pose: (m, 3, 2) the pose response
        (needed when ``noise.pose_var_rad2`` > 0); :param fixed: (m, 3, 3) fixed extra per
        window or ``None``; :param cap: the recording's slow-noise bound or ``None``.
    :raises ValueError: a covariance or design that cannot be factored.
    """
    z = ev.y.reshape(-1)
    model = ExcessModel.build(ev, noise, J_pose, fixed, cap)
    f0, x0 = model.fit_shared(X, z)
    lr = np.zeros(3)
    eps2 = np.zeros(3)
    for i in range(3):
        f1, x1 = model.fit_channel(X, z, i, x0)
        lr[i] = max(2.0 * (f0 - f1), 0.0)
        eps2[i] = model.size(float(x1[2]))
    ch = int(np.argmax(lr))
    p = 1.0 if lr[ch] <= 0 else min(1.0, 3.0 * 0.5 * float(chi2_dist.sf(lr[ch], 1)))
    return ChannelExcess(
        lr=lr,
        excess_var=eps2,
        channel=ch,
        p_value=p,
        shared_tau2=model.size(float(x0[0])) * model.shape,
        common_var=model.size(float(x0[1])) * model.shape,
    )
