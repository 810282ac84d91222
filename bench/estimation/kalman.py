"""Kalman filter and Rauch–Tung–Striebel smoother as pure functions over ``KalmanState(x, P)``.

The functional face of filterpy (``filterpy.kalman.predict/update/rts_smoother``), in the
notation of Särkkä, *Bayesian Filtering and Smoothing* (2013), §4.3 and §8.2:

    predict:  x⁻ = F x,   P⁻ = F P Fᵀ + Q
    update:   S = H P⁻ Hᵀ + R,   K = P⁻ Hᵀ S⁻¹,   x = x⁻ + K (z − h),
              P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ          (Joseph form)
    smoother: C_k = P_k Fᵀ (P⁻_{k+1})⁻¹,
              x^s_k = x_k + C_k (x^s_{k+1} − x⁻_{k+1}),
              P^s_k = P_k + C_k (P^s_{k+1} − P⁻_{k+1}) C_kᵀ

For the extended filter ``h`` is the measurement predicted at the prior mean and ``H``
its Jacobian there (Särkkä §5.2); for a linear model h = H x⁻.

:func:`update_diagonal` is the same update in information form, for many measurements
with independent noise (R diagonal): P = (P⁻⁻¹ + Hᵀ R⁻¹ H)⁻¹, x = x⁻ + P Hᵀ R⁻¹ (z − h);
its cost grows with the state size, not with the number of measurements.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class KalmanState:
    """Mean x (p,) and covariance P (p, p) of the state."""

    x: FloatArray
    P: FloatArray

    def __post_init__(self) -> None:
        x = np.asarray(self.x, dtype=float).reshape(-1)
        P = np.asarray(self.P, dtype=float)
        if P.shape != (x.shape[0], x.shape[0]):
            raise ValueError(f"KalmanState: P has shape {P.shape}, expected ({x.shape[0]}, {x.shape[0]})")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
            raise ValueError("KalmanState: x and P must be finite")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "P", P)


def _sym(P: FloatArray) -> FloatArray:
    return 0.5 * (P + P.T)


def predict(s: KalmanState, F: npt.ArrayLike | None = None, Q: npt.ArrayLike | None = None) -> KalmanState:
    """Time update with transition F (p, p; identity if None) and process noise Q (p, p; zero if None)."""
    p = s.x.shape[0]
    Fm = np.eye(p) if F is None else np.asarray(F, dtype=float)
    P = Fm @ s.P @ Fm.T
    if Q is not None:
        P = P + np.asarray(Q, dtype=float)
    return KalmanState(Fm @ s.x, _sym(P))


def update(
    s: KalmanState, z: npt.ArrayLike, h: npt.ArrayLike, H: npt.ArrayLike, R: npt.ArrayLike
) -> KalmanState:
    """Measurement update (Joseph form).

    :param z: (m,) measurement; :param h: (m,) its prediction at the prior mean.
    :param H: (m, p) Jacobian of the prediction; :param R: (m, m) measurement noise covariance.
    """
    Hm = np.atleast_2d(np.asarray(H, dtype=float))
    Rm = np.atleast_2d(np.asarray(R, dtype=float))
    innov = np.asarray(z, dtype=float).reshape(-1) - np.asarray(h, dtype=float).reshape(-1)
    PHt = s.P @ Hm.T
    S = Hm @ PHt + Rm
    Kg = np.linalg.solve(S, PHt.T).T
    IKH = np.eye(s.x.shape[0]) - Kg @ Hm
    P = IKH @ s.P @ IKH.T + Kg @ Rm @ Kg.T
    return KalmanState(s.x + Kg @ innov, _sym(P))


def update_diagonal(
    s: KalmanState, z: npt.ArrayLike, h: npt.ArrayLike, H: npt.ArrayLike, r_var: npt.ArrayLike
) -> KalmanState:
    """Measurement update for independent measurement noise, information form.

    :param r_var: (m,) measurement noise variances (R = diag(r_var)); other parameters as
        :func:`update`. Equal to :func:`update` with ``R = diag(r_var)`` (matrix inversion lemma).
    """
    Hm = np.atleast_2d(np.asarray(H, dtype=float))
    w = 1.0 / np.asarray(r_var, dtype=float).reshape(-1)
    innov = np.asarray(z, dtype=float).reshape(-1) - np.asarray(h, dtype=float).reshape(-1)
    info = np.linalg.inv(s.P) + (Hm.T * w) @ Hm
    P = _sym(np.asarray(np.linalg.inv(_sym(info)), dtype=float))
    return KalmanState(s.x + P @ (Hm.T @ (w * innov)), P)


def rts_smooth(
    filtered: Sequence[KalmanState], predicted: Sequence[KalmanState], F: npt.ArrayLike | None = None
) -> list[KalmanState]:
    """Rauch–Tung–Striebel smoother.

    :param filtered: states after the update of steps 0..N−1.
    :param predicted: states before the update of steps 0..N−1 (``predicted[k+1]`` is the
        prediction from ``filtered[k]`` with transition F).
    :param F: (p, p) transition, constant over the steps (identity if None).
    :returns: smoothed states 0..N−1; the last equals the last filtered one.
    """
    if len(filtered) != len(predicted) or not filtered:
        raise ValueError("rts_smooth: filtered and predicted must be non-empty and of equal length")
    p = filtered[0].x.shape[0]
    Fm = np.eye(p) if F is None else np.asarray(F, dtype=float)
    out = [filtered[-1]]
    for k in range(len(filtered) - 2, -1, -1):
        fk, pk1, sk1 = filtered[k], predicted[k + 1], out[-1]
        C = np.linalg.solve(pk1.P, Fm @ fk.P).T  # P_k Fᵀ (P⁻_{k+1})⁻¹, P⁻ symmetric
        x = fk.x + C @ (sk1.x - pk1.x)
        P = fk.P + C @ (sk1.P - pk1.P) @ C.T
        out.append(KalmanState(x, _sym(P)))
    out.reverse()
    return out
