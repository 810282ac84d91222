"""The encoders' step as pose scatter in each static window's covariance.

An encoder that reads in steps of q (the sidecar's ``table.encoder_resolution_deg``) leaves the
servo holding each pose anywhere within ±q/2 of the reading: each window's true angle of axis j
is θ_wj + u_wj, u_wj uniform on [−q/2, q/2], variance q²/12, independent between axes and
windows. The window mean then moves by K·∂f_w/∂θ·u_w to first order, so each window's
covariance gains the known block

    Q_w = (q²/12) · J_w J_wᵀ,   J_w = K · ∂f_w/∂θ   (3 × k, per degree),

J_w the encoder-offset response (``effects.geometry.EncoderOffset.jacobian``) at the first-order
K (least squares of the window means on bias + K·f: the block is a variance of µg on a
navigation-grade unit, so K's own error is negligible in it). Without a declared step it is
``None`` and the readings are taken as exact. Source: the uniform quantisation noise model
(Widrow & Kollár, "Quantization Noise", 2008, ch. 4) propagated through the attitude of
``bench.kinematics``.
"""

from __future__ import annotations

import numpy as np

from bench.diagnosis.effects.base import first_order_design
from bench.diagnosis.effects.geometry import EncoderOffset
from bench.diagnosis.evidence import FloatArray, StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


def quantisation_covariance(
    ev: StaticEvidence, K: FloatArray | None = None, th: Thresholds = THRESHOLDS
) -> FloatArray | None:
    """(m, 3, 3) Q_w of the module docstring (channel units²), or ``None`` (no table, no declared step).

    :param K: (3, 3) scale matrix (channel units per m/s²); ``None``: the first-order least squares.
    """
    step = ev.encoder_resolution_deg
    if step is None or ev.table_rad is None or ev.axis_vectors is None or not ev.orientation_known:
        return None
    if K is None:
        X0 = first_order_design(ev.f_m_s2)
        K = np.asarray(np.linalg.lstsq(X0, ev.y.reshape(-1), rcond=None)[0][3:12], dtype=float).reshape(3, 3)
    J = EncoderOffset().jacobian(ev, K, th.encoder_step_deg).reshape(ev.m, 3, -1)
    return np.asarray(step**2 / 12.0 * np.einsum("wik,wjk->wij", J, J), dtype=float)
