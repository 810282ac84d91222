"""Whether a library term in time or temperature beats what a slow bias wander can make.

A slow bias wander w_i(t) of channel i (``likelihood``: variance τ_i², correlation time T_c)
adds the same value to that channel at time t whatever the pose. A library term x(w) on
channel i that contains ``t`` or ``temp`` (a temperature that follows time) can therefore
be imitated by the wander only through the part of its signature that is a common function
of time; the part that changes with the pose (f_z·t changes sign when the unit turns over)
no wander can make. Two cases:

- a term that is a function of time or temperature alone (``t^2``, ``temp^2``, ``t*temp``):
  all of it is common-mode. It is judged like the catalogue's ``bias_drift`` and
  ``temperature_bias`` (``WANDER_LIKE``: the likelihood ratio with each channel's
  own wander re-estimated in both models must also pass the gate);
- a pose-modulated term (a factor ``f_*`` or ``abs(f_*)`` besides ``t`` or ``temp``): the
  confirmatory statistic is the Wald statistic of its column a given the model X *and* the
  wander's leading mode on its channel, B_i = s with s = (t_w − t̄)/span (on channel i
  only),

      LR_mod = χ²([X B_i]) − χ²([X B_i a]),   both under the extended model's noise C,

  against the same gate q·F_{1−α}(q, n − p − b), b = 1 (0 when s on channel i is already
  in the span of X, e.g. with ``bias_drift`` of that channel in the model). Under H0 (no
  term; the wander's trend in the span of B_i, its rest in C) LR_mod ~ q·F(q, n − p − b).
  A term must pass both its ordinary test and this one (an intersection of two tests at
  level α has level ≤ α, so the false-alarm rate does not grow); what it loses is only the
  share of its signature that a trend in time would explain.

Why the trend alone: for a Gauss–Markov wander sampled at 12 evenly spaced windows, the
share of its variance beyond its mean (which the bias absorbs) held by s is 36 %, 51 % and
57 % for T_c = 0.3, 1 and 3 spans (the noise model's grid), within 2 % of its leading
Karhunen–Loève mode; s and s² together hold 55, 69 and 74 %. The trend is what a term that
follows time borrows from a wander; the rest is carried by the slow-noise level τ² when
REML has not let it collapse (with the term in the model it often does, the term having
taken the trend: then this column is what stands in for the wander). Measured: the false
``abs(f_y)*t`` on az of ``example_static12`` (a wander's trend, |cos| 0.90 with a drift)
falls from 39.5 to 3.7 with the trend (4.0 with trend and curve), the injected f_z·t of
``test_injected_alignment_creep…`` from 39.7 to 31.3 (22.6 with the curve too, which would
lose it). The alternative, the full likelihood ratio with each channel's wander
re-estimated, charges a pose-modulated term for the whole channel's excess scatter and
loses that f_z·t too (its evidence has no window samples to bound the wander).
"""

from __future__ import annotations

import numpy as np

from bench.diagnosis.effects.base import FloatArray, channel_column
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import NoiseParams, gls
from bench.estimation.window_covariance import WindowCovariance

WANDER_LIKE = ("bias_drift", "temperature_bias", "thermal_lag")
"""Catalogue effects whose signature a slow bias wander can imitate (a trend in time, or in a temperature
that follows time). With such an effect in the model, REML can let the wander collapse to
nothing (a 12-window run holds one or two correlation times of wander, whose trend the
effect then takes), and the Wald statistic under that noise compares the trend with white
noise instead of with the wander the recording shows. Such a claim must also pass the full
likelihood ratio 2 (ℓ_ML,with − ℓ_ML,without) in which each channel's own slow wander
(level and correlation time, REML) is re-estimated in both models: the wander the recording
shows without the effect competes with it, and the smaller statistic counts. The library's
terms in time or temperature alone are judged the same way; its pose-modulated terms in time
or temperature pass a test of the part of their signature no wander can make instead
(``wander_modes``)."""


def wander_note(effect: str, lr: float, lr_wander: float, gate: float, noise: NoiseParams) -> str:
    """Why a wander-like effect was not admitted although it fits (``select``)."""
    tau = ", ".join(f"{np.sqrt(t):.2g}" for t in noise.tau2)
    corr = "" if noise.corr_time_s <= 0 else f", correlation time {noise.corr_time_s:.0f} s"
    what = {
        "bias_drift": "a drift",
        "temperature_bias": "a temperature coefficient",
        "thermal_lag": "a temperature coefficient through a thermal lag",
    }.get(effect, "a term in time or temperature")
    return (
        f"{what} fits (likelihood ratio {lr:.1f} with the wander it leaves), but the slow wander the "
        f"recording shows without it (sigma = [{tau}] channel units{corr}) makes such a trend too "
        f"(likelihood ratio {lr_wander:.1f} with each channel's wander re-estimated, gate {gate:.1f}): "
        "this recording cannot tell the effect from a wander; longer or repeated runs can"
    )


TIME_BASES = ("t", "temp")
"""Base quantities (``docs/cli-contract.md`` grammar) a bias wander can follow."""


def _bases(term: str) -> list[str]:
    return [factor.split("^")[0] for factor in term.split("*")]


def follows_time(term: str) -> bool:
    """Whether a term of the contract grammar has a factor ``t`` or ``temp``."""
    return any(b in TIME_BASES for b in _bases(term))


def pose_modulated(term: str) -> bool:
    """Whether a term has a factor that changes with the pose (``f_*``, ``abs(f_*)``)."""
    return any(b.startswith(("f_", "abs(f_")) for b in _bases(term))


def wander_basis(ev: StaticEvidence, channel: int) -> FloatArray:
    """(3m, 1) the wander's leading mode on ``channel``: s = (t_w − t̄)/span."""
    span = float(np.ptp(ev.mid_s))
    s = (ev.mid_s - float(np.mean(ev.mid_s))) / (span if span > 0 else 1.0)
    return channel_column(ev, channel, s)


def modulated_lr(
    ev: StaticEvidence,
    X: FloatArray,
    a: FloatArray,
    channel: int,
    C: WindowCovariance,
    leverage_min: float,
) -> tuple[float, int]:
    """LR_mod of the module docstring and the number b of wander columns it conditions on.

    :param X: (3m, p) the model without the term; :param a: (3m, q) the term's columns.
    :param channel: the term's channel; :param C: the extended model's noise covariance.
    :param leverage_min: wander columns with less than this share of their norm beyond X are left
        out (``Thresholds.relative_leverage_min``).
    :returns: (LR_mod ≥ 0, b). LR_mod is 0 when the term lies in the span of X and B_i.
    """
    B = wander_basis(ev, channel)
    Q, _ = np.linalg.qr(X)
    Bp = B - Q @ (Q.T @ B)
    keep = np.linalg.norm(Bp, axis=0) > leverage_min * np.linalg.norm(B, axis=0)
    X0 = np.hstack([X, B[:, keep]])
    z = ev.y.reshape(-1)
    q = a.shape[1]
    try:
        fit = gls(np.hstack([X0, a]), z, C)
    except ValueError:
        return 0.0, int(np.sum(keep))
    # the Wald form θ̂_aᵀ cov_aa⁻¹ θ̂_a equals the χ² difference under a fixed C and does not
    # subtract two large χ² values
    th = fit.theta[-q:]
    lr = float(th @ np.linalg.solve(fit.cov[-q:, -q:], th))
    return max(lr, 0.0), int(np.sum(keep))


def modulated_note(term_label: str, lr: float, lr_mod: float, gate: float) -> str:
    """Why a pose-modulated term that follows time was not admitted although it fits."""
    return (
        f"follows time (likelihood ratio {lr:.1f}), but with a trend in time on its channel, which a "
        f"slow bias wander makes whatever the pose, its pose-modulated part gives only "
        f"{lr_mod:.1f} (gate {gate:.1f}): this recording cannot tell {term_label} from a wander"
    )
