"""Table motion of a recording reduced to the regressors of the moving-table model.

From the sampled, unwrapped encoder angles (``recording-format.md``) :func:`prepare_motion`
forms, per sample, G = Mᵀ R_inᵀ and B = Mᵀ R_inᵀ A R_in (``dynamic_model``) and their first
and second time derivatives, the samples the fit may use and the peak rate.

Angle derivatives (the choice for ω̇): the unwrapped encoder angles are differentiated by
a cubic Savitzky–Golay filter over ``DERIVATIVE_WINDOW_S`` (at least 7 samples), so the
encoder quantisation noise in ω̇ stays below 1e-3 rad/s² at 100 Hz–1 kHz (a tangential
error under 1e-4 m/s² at 0.1 m). A cubic is exact for smooth motion but not across a
jump of the angular acceleration (the corners of a trapezoidal rate ramp); samples whose
third-derivative estimate exceeds ``CORNER_JERK_RAD_S3``, and those within half a window
of them, are left out of the fit (``MotionData.valid``).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.signal import savgol_filter

from bench.kinematics import angular_acceleration, angular_velocity, inner_attitude

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

DERIVATIVE_WINDOW_S = 0.07
"""Span of the Savitzky–Golay window for rates, accelerations and Ġ, Ḃ (s)."""
MIN_WINDOW_SAMPLES = 7
GAP_FACTOR = 1.5
"""A time step longer than this many median steps is a gap (dropped DAQ blocks): derivatives
are taken on each stretch between gaps, and a stretch shorter than the window is left out."""
CORNER_JERK_RAD_S3 = 2.0
"""|d³θ/dt³| above this marks a corner of the rate profile (rad/s³); a smooth oscillation
of the procedures stays below 0.3 rad/s³."""
KINEMATICS_CHUNK = 1 << 15
"""Samples whose attitude, rate and acceleration are formed at once in :func:`prepare_motion`:
the partial rotation products and skew matrices are (chunk, 3, 3) temporaries, not (n, 3, 3)."""
PREDICT_CHUNK = 1 << 15
"""Samples whose prediction or specific force :func:`predict` and :func:`specific_force` form at
once: with ``time_skew`` the corrected regressors G_δ, B_δ and their δ-derivatives are
(chunk, 3, 3) temporaries, not (n, 3, 3)."""


@dataclass(frozen=True)
class MotionData:
    """The table motion of a recording, reduced to what the model needs (all (n, …)).

    :param t_s: (n,) time (s).
    :param G: (n, 3, 3) Mᵀ R_inᵀ; :param G_dot: its time derivative (1/s).
    :param B: (n, 3, 3) Mᵀ R_inᵀ A R_in (1/s²); :param B_dot: its time derivative (1/s³).
    :param G_ddot: (n, 3, 3) second derivative of G; :param B_ddot: of B.
    :param valid: (n,) samples the fit may use (not at a rate-profile corner).
    :param peak_rate_rad_s: max |ω| (rad/s).
    """

    t_s: FloatArray
    G: FloatArray
    G_dot: FloatArray
    B: FloatArray
    B_dot: FloatArray
    G_ddot: FloatArray
    B_ddot: FloatArray
    valid: BoolArray
    peak_rate_rad_s: float

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t_s.shape[0])

    def take(self, idx: slice | npt.NDArray[np.int64]) -> MotionData:
        """The samples ``idx`` (a slice or index array)."""
        return MotionData(
            self.t_s[idx],
            self.G[idx],
            self.G_dot[idx],
            self.B[idx],
            self.B_dot[idx],
            self.G_ddot[idx],
            self.B_ddot[idx],
            self.valid[idx],
            self.peak_rate_rad_s,
        )


def _skew(v: FloatArray) -> FloatArray:
    z = np.zeros(v.shape[0])
    return np.stack(
        [
            np.stack([z, -v[:, 2], v[:, 1]], 1),
            np.stack([v[:, 2], z, -v[:, 0]], 1),
            np.stack([-v[:, 1], v[:, 0], z], 1),
        ],
        1,
    )


def sample_chunks(n: int) -> list[slice]:
    """Consecutive slices of at most :data:`PREDICT_CHUNK` samples covering ``range(n)``."""
    return [slice(a, min(a + PREDICT_CHUNK, n)) for a in range(0, n, PREDICT_CHUNK)]


def window_samples(sample_rate_hz: float, window_s: float = DERIVATIVE_WINDOW_S) -> int:
    """Odd Savitzky–Golay window length spanning ``window_s``, at least 7 samples."""
    w = max(MIN_WINDOW_SAMPLES, round(window_s * sample_rate_hz))
    return w if w % 2 else w + 1


def prepare_motion(
    t_s: npt.ArrayLike,
    angles_rad_unwrapped: npt.ArrayLike,
    axis_vectors: npt.ArrayLike,
    mount: npt.ArrayLike,
    *,
    window_s: float = DERIVATIVE_WINDOW_S,
) -> MotionData:
    """Kinematic regressors G, B and their derivatives from sampled encoder angles.

    :param t_s: (n,) uniformly sampled time (s; steps within 5 % of the median), gaps allowed.
    :param angles_rad_unwrapped: (n, k) unwrapped axis angles (rad).
    :param axis_vectors: (k, 3) unit axes, outermost first.
    :param mount: (3, 3) mount rotation M.
    :raises ValueError: too few samples, non-uniform (other than gaps) or non-increasing time.
    """
    t = np.asarray(t_s, dtype=float).reshape(-1)
    q = np.asarray(angles_rad_unwrapped, dtype=float)
    q = q[:, None] if q.ndim == 1 else q
    if t.shape[0] < MIN_WINDOW_SAMPLES or q.shape[0] != t.shape[0]:
        raise ValueError(
            f"motion needs >= {MIN_WINDOW_SAMPLES} samples and one angle row per time, "
            f"got t {t.shape}, angles {q.shape}"
        )
    dt = np.diff(t)
    h = float(np.median(dt))
    gap = dt > GAP_FACTOR * h
    if not (np.all(np.isfinite(t)) and np.all(dt > 0)) or np.max(np.abs(dt[~gap] - h)) > 0.05 * h:
        raise ValueError(
            "motion: time stamps must be finite, increasing and uniform within 5 % of the step "
            f"(gaps longer than {GAP_FACTOR} steps are allowed)"
        )
    w = window_samples(1.0 / h, window_s)
    cuts = np.concatenate([[0], np.flatnonzero(gap) + 1, [t.shape[0]]])
    runs = [(int(a), int(b)) for a, b in itertools.pairwise(cuts) if b - a >= w]
    if not runs:
        raise ValueError(f"motion: no stretch without gaps as long as the {w}-sample derivative window")
    usable = np.zeros(t.shape[0], dtype=bool)
    for a, b in runs:
        usable[a:b] = True

    def sg(x: FloatArray, deriv: int) -> FloatArray:
        """Savitzky–Golay derivative of x along time, run by run between gaps (zero outside runs)."""
        if runs == [(0, x.shape[0])]:  # one run without gaps: the filter's own output, no zeroed copy
            return np.asarray(
                savgol_filter(x, w, 3, deriv=deriv, delta=h, axis=0, mode="interp"), dtype=float
            )
        out = np.zeros_like(x)
        for a, b in runs:
            out[a:b] = savgol_filter(x[a:b], w, 3, deriv=deriv, delta=h, axis=0, mode="interp")
        return out

    rates, accels, jerk = sg(q, 1), sg(q, 2), sg(q, 3)
    corner = np.any(np.abs(jerk) > CORNER_JERK_RAD_S3, axis=1)
    del jerk
    if corner.any():
        corner = np.convolve(corner.astype(float), np.ones(w), mode="same") > 0
    corner |= ~usable
    M = np.asarray(mount, dtype=float).reshape(3, 3)
    n = t.shape[0]
    G, B = np.empty((n, 3, 3)), np.empty((n, 3, 3))
    peak_rate = 0.0
    for a in range(0, n, KINEMATICS_CHUNK):  # sample by sample: chunks only bound the temporaries
        s = slice(a, a + KINEMATICS_CHUNK)
        R_in = inner_attitude(axis_vectors, q[s])
        G[s] = np.einsum("ji,njk->nik", M, np.transpose(R_in, (0, 2, 1)))
        omega = angular_velocity(axis_vectors, q[s], rates[s])
        W = _skew(omega)
        A = _skew(angular_acceleration(axis_vectors, q[s], rates[s], accels[s])) + W @ W
        B[s] = G[s] @ A @ R_in
        peak_rate = max(peak_rate, float(np.max(np.linalg.norm(omega, axis=1))))
    del rates, accels
    return MotionData(
        t_s=t,
        G=G,
        G_dot=sg(G, 1),
        B=B,
        B_dot=sg(B, 1),
        G_ddot=sg(G, 2),
        B_ddot=sg(B, 2),
        valid=~corner,
        peak_rate_rad_s=peak_rate,
    )
