"""Extended Kalman filter and RTS smoother of the dynamic model, as in the moving-table papers.

State: the parameter vector θ of ``dynamic_model`` (bias, K, lever arm, …), constant in
time except for an optional random walk of the bias, x_{k+1} = x_k + w_k with
Q = diag(q) · Δt, q = ``bias_walk_var_per_s`` on the three bias states (channel units² per s),
zero elsewhere. Measurements: the raw samples of a batch of ``batch_s`` seconds
(all samples of the batch update at once, information form, R = diag(σ_c²) with σ_c the
per-channel white-noise level), linearised at the prior mean of each batch (the extended
filter, Särkkä 2013 §5.2). The prior is the sensor's spread before calibration
(:class:`Prior`, defaults of an ADXL325-like unit: 15 mg bias, 1 % scale, 15′
misalignment); the start is the linear least-squares start of the batch fit, whose own
information is negligible against the data's only if the prior is broad, which it is.
The measurement is bilinear in K and the lever arm, so a single pass from a start that is
centimetres off linearises its first batches badly; ``passes=2`` (the default) runs the
filter again from the first pass's final mean with the same broad prior (a relinearisation,
as the iterated extended filter does per step, Särkkä 2013 §5.5).

With no bias walk the smoothed state equals the final filtered one; with a walk the
smoother returns the bias along the run. The filter's covariance assumes white noise: it
is the white-noise bound of the batch fit, not the sandwich.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.dynamic_batch import BiasReference
from bench.estimation.dynamic_model import ModelSpec, predict
from bench.estimation.kalman import KalmanState, rts_smooth, update_diagonal
from bench.estimation.kalman import predict as kf_predict
from bench.estimation.motion_data import MotionData, MotionSamples

FloatArray = npt.NDArray[np.float64]

BATCH_S = 0.1
TAKE_SAMPLES = 20_000
"""Samples whose regressors are taken from the motion at once, for the batches they hold: a
pass forms (or copies) each sample's regressors once, not a batch and its derivative windows
at a time."""
ARCMIN_RAD = np.pi / (180.0 * 60.0)


@dataclass(frozen=True)
class Prior:
    """One-sigma spread of a unit before calibration (relative to the nominal K diagonal).

    :param bias_m_s2: bias spread (m/s²); default 15 mg.
    :param scale_rel: scale-factor spread; default 1 %.
    :param misalignment_rad: off-diagonal spread (rad); default 15′.
    :param lever_arm_m: lever-arm spread (m); :param k2_per_g: nonlinearity spread (1/g);
    :param tilt_rad: levelling spread (rad); :param delay_s: time-skew spread (s).
    """

    bias_m_s2: float = 15e-3 * 9.80665
    scale_rel: float = 0.01
    misalignment_rad: float = 15.0 * ARCMIN_RAD
    lever_arm_m: float = 0.1
    k2_per_g: float = 0.01
    tilt_rad: float = 0.01
    delay_s: float = 0.01

    def sigma(self, spec: ModelSpec, K_nominal: FloatArray) -> FloatArray:
        """(p,) prior one-sigma per parameter of ``spec``."""
        kd = np.abs(np.diag(K_nominal))
        s = np.zeros(spec.n_params)
        s[:3] = self.bias_m_s2 * kd
        Ks = np.outer(kd, np.ones(3)) * self.misalignment_rad
        Ks[np.diag_indices(3)] = kd * self.scale_rel
        s[3:12] = Ks.reshape(9)
        per = {
            "lever_arm": self.lever_arm_m,
            "proof_mass_offsets": self.lever_arm_m,
            "nonlinearity_quadratic": self.k2_per_g,
            "table_tilt": self.tilt_rad,
            "time_skew": self.delay_s,
        }
        for t in spec.terms:
            s[spec.index(t)] = per[t]
        return s


@dataclass(frozen=True)
class KalmanRun:
    """Result of :func:`run_dynamic_kalman`.

    :param t_s: (N,) end time of each batch (s).
    :param filtered: (N, p) filtered means; :param filtered_sigma: (N, p) their one-sigma.
    :param smoothed: (N, p) smoothed means; :param smoothed_sigma: (N, p).
    :param final: the last filtered state (the estimate from all data).
    :param bias_reference: what the bias sigma describes
        (:data:`bench.estimation.dynamic_batch.BiasReference`): the filter's covariance is the
        white bound of the run, so the run's mean bias.
    """

    names: tuple[str, ...]
    t_s: FloatArray
    filtered: FloatArray
    filtered_sigma: FloatArray
    smoothed: FloatArray
    smoothed_sigma: FloatArray
    final: KalmanState
    bias_reference: BiasReference = "run_mean"


def run_dynamic_kalman(
    m: MotionData,
    y: npt.ArrayLike,
    g_m_s2: float,
    lever_arm_m: npt.ArrayLike,
    spec: ModelSpec,
    x0: FloatArray,
    noise_sigma: npt.ArrayLike,
    *,
    prior: Prior | None = None,
    batch_s: float = BATCH_S,
    bias_walk_var_per_s: float = 0.0,
    smooth: bool = True,
    passes: int = 2,
) -> KalmanRun:
    """Filter (and smooth) θ through the recording.

    :param m: motion; :param y: (n, 3) raw samples; :param g_m_s2: local gravity (m/s²).
    :param lever_arm_m: (3,) believed lever arm (m); :param x0: (p,) start.
    :param noise_sigma: (3,) white-noise sigma per channel (channel units).
    :param batch_s: samples per update (s).
    """
    Y = np.asarray(y, dtype=float)
    lever = np.asarray(lever_arm_m, dtype=float).reshape(3)
    sig = np.asarray(noise_sigma, dtype=float).reshape(3)
    if Y.shape != (m.n, 3) or not np.all(np.isfinite(Y)) or not np.all(sig > 0):
        raise ValueError(f"Kalman: raw must be finite ({m.n}, 3) and noise sigma > 0, got {Y.shape}, {sig}")
    p = spec.n_params
    pr = prior or Prior()
    P0 = np.diag(pr.sigma(spec, np.asarray(x0[3:12]).reshape(3, 3)) ** 2)
    dt = float(np.median(np.diff(m.t_s)))
    per = max(1, round(batch_s / dt))
    Q = np.zeros((p, p))
    Q[:3, :3] = np.eye(3) * bias_walk_var_per_s * per * dt
    idx = np.flatnonzero(m.valid)
    cuts = np.arange(0, idx.shape[0], per)
    start = np.asarray(x0, dtype=float)
    for _ in range(max(1, passes)):
        state = KalmanState(start, P0)
        filt: list[KalmanState] = []
        pred: list[KalmanState] = []
        times = np.empty(cuts.shape[0])
        block: MotionSamples | None = None
        b0 = 0
        for j, a in enumerate(cuts):
            sel = idx[a : a + per]
            if block is None or a + sel.shape[0] > b0 + block.n:  # the regressors of the next batches at once
                b0 = int(a)
                block = m.take(idx[a : a + per * max(1, TAKE_SAMPLES // per)], rates=spec.needs_rates)
            prior_k = state if j == 0 else kf_predict(state, None, Q if bias_walk_var_per_s else None)
            ms = block.take(slice(a - b0, a - b0 + sel.shape[0]))
            raw, J = predict(prior_k.x, ms, spec, g_m_s2, lever, jacobian=True)
            assert J is not None
            state = update_diagonal(
                prior_k, Y[sel].reshape(-1), raw.reshape(-1), J.reshape(-1, p), np.tile(sig**2, sel.shape[0])
            )
            pred.append(prior_k)
            filt.append(state)
            times[j] = m.t_s[sel[-1]]
        start = filt[-1].x if not bias_walk_var_per_s else filt[0].x
    sm = rts_smooth(filt, pred) if smooth else filt
    return KalmanRun(
        names=tuple(spec.names),
        t_s=times,
        filtered=np.array([s.x for s in filt]),
        filtered_sigma=np.array([np.sqrt(np.diag(s.P)) for s in filt]),
        smoothed=np.array([s.x for s in sm]),
        smoothed_sigma=np.array([np.sqrt(np.diag(s.P)) for s in sm]),
        final=filt[-1],
    )
