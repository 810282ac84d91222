"""Measurement model of an accelerometer triad on a moving table, with its exact Jacobian.

Kinematics (``recording-format.md``; Titterton & Weston, *Strapdown Inertial Navigation
Technology*, 2nd ed., §3.2): with R_in(t) the innermost table frame's attitude, M the
mount rotation, ω and ω̇ the innermost frame's rate and angular acceleration (base
coordinates) and A = [ω̇]× + [ω]×², the specific force that sensor axis i feels at a
point q_i of the innermost table frame is

    f_i(t) = e_iᵀ G(t) g_base + e_iᵀ B(t) q_i,     G = Mᵀ R_inᵀ,   B = Mᵀ R_inᵀ A R_in

with g_base = Rot(x, a)·Rot(y, b)·[0, 0, g] = g·[sin b, −cos b sin a, cos b cos a] (the
``table_tilt`` of ``cli-contract.md``). Without the size effect every axis sits at the
lever arm r (q_i = r); with it (``proof_mass_offsets``) each axis has its own q_i
(DESIGN.md §3, the rate-table paper). f is linear in g_base and q, and so is its time
derivatives ḟ = Ġ g_base + Ḃ q and f̈, with Ġ, Ḃ, G̈, B̈ precomputed by differentiating G,
B along time.

``time_skew``: the sample at t saw the table at t − δ,
f_δ(t) = f(t − δ) ≈ f(t) − δ·ḟ(t) + δ²/2·f̈(t) (second order; with |f⃛| ≲ g·ω³ the neglected
δ³/6·f⃛ is below 1e-6 g for δ ≤ 10 ms at the procedures' rates, ω ≤ 3.5 rad/s).

Sensor (``cli-contract.md``): raw = b + K f_δ + diag(K) ⊙ k2 ⊙ f_δ² / g0.

Angle derivatives (the choice for ω̇): the unwrapped encoder angles are differentiated by
a cubic Savitzky–Golay filter over ``DERIVATIVE_WINDOW_S`` (at least 7 samples), so the
encoder quantisation noise in ω̇ stays below 1e-3 rad/s² at 100 Hz–1 kHz (a tangential
error under 1e-4 m/s² at 0.1 m). A cubic is exact for smooth motion but not across a
jump of the angular acceleration (the corners of a trapezoidal rate ramp); samples whose
third-derivative estimate exceeds ``CORNER_JERK_RAD_S3``, and those within half a window
of them, are left out of the fit (``MotionData.valid``).

Parameter vector θ (``ModelSpec.names``): bias (3, channel units), K (9, row-major,
channel unit per m/s²), then the chosen terms in the order of ``TERM_ORDER``: lever_arm
r (3, m) or proof_mass_offsets q (9: q_x, q_y, q_z rows, m), nonlinearity_quadratic k2
(3, 1/g), table_tilt (a, b) (rad), time_skew δ (s).
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

G0_M_S2 = 9.80665
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
TERM_ORDER = ("lever_arm", "proof_mass_offsets", "nonlinearity_quadratic", "table_tilt", "time_skew")
_AX = "xyz"


@dataclass(frozen=True)
class ModelSpec:
    """Which terms beyond bias and K the model carries (a subset of ``TERM_ORDER``).

    ``proof_mass_offsets`` implies the lever arm: the three proof-mass positions q_i
    replace r.
    """

    terms: tuple[str, ...] = ("lever_arm",)

    def __post_init__(self) -> None:
        bad = [t for t in self.terms if t not in TERM_ORDER]
        if bad:
            raise ValueError(f"unknown dynamic model term(s) {bad}; known: {list(TERM_ORDER)}")
        ordered = tuple(t for t in TERM_ORDER if t in self.terms)
        if "proof_mass_offsets" in ordered and "lever_arm" in ordered:
            ordered = tuple(t for t in ordered if t != "lever_arm")
        object.__setattr__(self, "terms", ordered)

    @property
    def names(self) -> list[str]:
        """Parameter names in θ order."""
        out = [f"bias_{a}" for a in _AX] + [f"K_{a}{b}" for a in _AX for b in _AX]
        for t in self.terms:
            if t == "lever_arm":
                out += [f"r_{a}" for a in _AX]
            elif t == "proof_mass_offsets":
                out += [f"q_{a}{b}" for a in _AX for b in _AX]
            elif t == "nonlinearity_quadratic":
                out += [f"k2_{a}" for a in _AX]
            elif t == "table_tilt":
                out += ["tilt_a", "tilt_b"]
            else:
                out += ["delay_s"]
        return out

    @property
    def n_params(self) -> int:
        """Length of θ."""
        return len(self.names)

    def index(self, term: str) -> slice:
        """Slice of θ holding ``term`` (``bias``, ``scale_matrix`` or one of ``terms``)."""
        sizes = {
            "lever_arm": 3,
            "proof_mass_offsets": 9,
            "nonlinearity_quadratic": 3,
            "table_tilt": 2,
            "time_skew": 1,
        }
        if term == "bias":
            return slice(0, 3)
        if term == "scale_matrix":
            return slice(3, 12)
        start = 12
        for t in self.terms:
            if t == term:
                return slice(start, start + sizes[t])
            start += sizes[t]
        raise KeyError(f"term {term!r} is not in this model ({list(self.terms)})")


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


def gravity_base(theta: FloatArray, spec: ModelSpec, g_m_s2: float) -> tuple[FloatArray, FloatArray]:
    """g_base (3,) and ∂g_base/∂(a, b) (3, 2) (zeros without ``table_tilt``)."""
    if "table_tilt" not in spec.terms:
        return np.array([0.0, 0.0, g_m_s2]), np.zeros((3, 2))
    a, b = theta[spec.index("table_tilt")]
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    gb = g_m_s2 * np.array([sb, -cb * sa, cb * ca])
    d = g_m_s2 * np.array([[0.0, cb], [-cb * ca, sb * sa], [-cb * sa, -sb * ca]])
    return gb, d


def positions(theta: FloatArray, spec: ModelSpec, lever_arm_m: FloatArray) -> FloatArray:
    """(3, 3) proof-mass position of each axis (rows, innermost frame, m)."""
    if "proof_mass_offsets" in spec.terms:
        return theta[spec.index("proof_mass_offsets")].reshape(3, 3)
    r = theta[spec.index("lever_arm")] if "lever_arm" in spec.terms else np.asarray(lever_arm_m, dtype=float)
    return np.tile(np.asarray(r, dtype=float).reshape(1, 3), (3, 1))


def _forces(
    theta: FloatArray, m: MotionData, spec: ModelSpec, g: float, lever_arm_m: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """f_δ (n,3), ∂f_δ/∂δ = −ḟ + δ f̈ (n,3), and the effective regressors G_δ, B_δ (n,3,3)."""
    gb, _ = gravity_base(theta, spec, g)
    Q = positions(theta, spec, lever_arm_m)
    if "time_skew" not in spec.terms:
        return m.G @ gb + np.einsum("nic,ic->ni", m.B, Q), np.zeros((m.n, 3)), m.G, m.B
    d = float(theta[spec.index("time_skew")][0])
    Ge = m.G - d * m.G_dot + 0.5 * d * d * m.G_ddot
    Be = m.B - d * m.B_dot + 0.5 * d * d * m.B_ddot
    dGe = d * m.G_ddot - m.G_dot
    dBe = d * m.B_ddot - m.B_dot
    f = Ge @ gb + np.einsum("nic,ic->ni", Be, Q)
    return f, dGe @ gb + np.einsum("nic,ic->ni", dBe, Q), Ge, Be


def specific_force(
    theta: FloatArray, m: MotionData, spec: ModelSpec, g_m_s2: float, lever_arm_m: FloatArray
) -> FloatArray:
    """(n, 3) specific force f_δ each axis feels (m/s²), lever arm, tilt and skew included.

    Formed :data:`PREDICT_CHUNK` samples at a time: each sample's force depends on that sample
    alone, so the chunks bound the (chunk, 3, 3) skew-corrected regressors without changing a bit.
    """
    out = np.empty((m.n, 3))
    for s in sample_chunks(m.n):
        out[s] = _forces(theta, m.take(s), spec, g_m_s2, lever_arm_m)[0]
    return out


def predict(
    theta: FloatArray,
    m: MotionData,
    spec: ModelSpec,
    g_m_s2: float,
    lever_arm_m: FloatArray,
    *,
    jacobian: bool = False,
) -> tuple[FloatArray, FloatArray | None]:
    """Model raw output (n, 3) and, if asked, ∂raw/∂θ (n, 3, p).

    Without the Jacobian the output is formed :data:`PREDICT_CHUNK` samples at a time (each
    sample's prediction depends on that sample alone), so a whole recording's prediction holds
    only (chunk, 3, 3) temporaries; with it, the caller chooses the samples (the Jacobian is
    itself (n, 3, p)).

    :param theta: (p,) parameters in ``spec.names`` order.
    :param lever_arm_m: (3,) lever arm used when the model does not fit it (m).
    """
    if not jacobian:
        out = np.empty((m.n, 3))
        for s in sample_chunks(m.n):
            out[s] = _predict_samples(theta, m.take(s), spec, g_m_s2, lever_arm_m, jacobian=False)[0]
        return out, None
    return _predict_samples(theta, m, spec, g_m_s2, lever_arm_m, jacobian=True)


def _predict_samples(
    theta: FloatArray,
    m: MotionData,
    spec: ModelSpec,
    g_m_s2: float,
    lever_arm_m: FloatArray,
    *,
    jacobian: bool,
) -> tuple[FloatArray, FloatArray | None]:
    """:func:`predict` on all of ``m``'s samples at once."""
    b, K = theta[:3], theta[3:12].reshape(3, 3)
    f, df_dd, Ge, Be = _forces(theta, m, spec, g_m_s2, lever_arm_m)
    dK = np.diag(K)
    k2 = (
        theta[spec.index("nonlinearity_quadratic")] if "nonlinearity_quadratic" in spec.terms else np.zeros(3)
    )
    raw = b + f @ K.T + dK * k2 * f * f / G0_M_S2
    if not jacobian:
        return raw, None
    n, p = m.n, spec.n_params
    J = np.zeros((n, 3, p))
    J[:, :, :3] = np.eye(3)
    for i in range(3):
        J[:, i, 3 + 3 * i : 6 + 3 * i] = f
        J[:, i, 3 + 4 * i] += k2[i] * f[:, i] ** 2 / G0_M_S2
    D = np.broadcast_to(K, (n, 3, 3)).copy()  # ∂raw/∂f
    D[:, [0, 1, 2], [0, 1, 2]] += 2.0 * dK * k2 * f / G0_M_S2
    for t in spec.terms:
        s = spec.index(t)
        if t == "lever_arm":
            J[:, :, s] = D @ Be
        elif t == "proof_mass_offsets":
            for i in range(3):  # f_i depends on q_i only
                J[:, :, s.start + 3 * i : s.start + 3 * i + 3] = D[:, :, i, None] * Be[:, i, None, :]
        elif t == "nonlinearity_quadratic":
            J[:, [0, 1, 2], [s.start, s.start + 1, s.start + 2]] = dK * f * f / G0_M_S2
        elif t == "table_tilt":
            _, dg = gravity_base(theta, spec, g_m_s2)
            J[:, :, s] = D @ (Ge @ dg)
        else:
            J[:, :, s.start] = np.einsum("nij,nj->ni", D, df_dd)
    return raw, J


def initial_theta(spec: ModelSpec, bias: FloatArray, K: FloatArray, lever_arm_m: FloatArray) -> FloatArray:
    """θ with the given bias and K, the lever arm at ``lever_arm_m`` and every other term zero."""
    theta = np.zeros(spec.n_params)
    theta[:3] = bias
    theta[3:12] = np.asarray(K, dtype=float).reshape(9)
    for t in spec.terms:
        if t == "lever_arm":
            theta[spec.index(t)] = lever_arm_m
        elif t == "proof_mass_offsets":
            theta[spec.index(t)] = np.tile(np.asarray(lever_arm_m, dtype=float), 3)
    return theta
