"""The pose error, a catch-all variance component, as the selection's last group (``select``).

The pose variance is a boundary parameter: LR = 2 Δℓ_REML is judged against the 50:50 mixture
of χ²_0 and χ²_1 (the χ²_1 quantile at 2α); its BIC change is the conditional one given its
angles, charged its effective degrees of freedom (``catch_all``), and it must show the scatter
its physics implies on every channel.
"""

from __future__ import annotations

import math
from dataclasses import replace

from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.catch_all import pose_check
from bench.diagnosis.effects import pose_response
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.model_state import POSE_ERROR, ModelState, Step, design, fit_model, scale_matrix_of
from bench.diagnosis.thresholds import Thresholds
from bench.diagnosis.wander_cap import SlowNoiseCap


def pose_step(
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
