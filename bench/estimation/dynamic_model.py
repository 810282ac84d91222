"""Measurement model of an accelerometer triad on a moving table, with its exact Jacobian.

Kinematics (``docs/recording-format.md``; Titterton & Weston, *Strapdown Inertial Navigation
Technology*, 2nd ed., §3.2): with R_in(t) the innermost table frame's attitude, M the
mount rotation, ω and ω̇ the innermost frame's rate and angular acceleration (base
coordinates) and A = [ω̇]× + [ω]×², the specific force that sensor axis i feels at a
point q_i of the innermost table frame is

    f_i(t) = e_iᵀ G(t) g_base + e_iᵀ B(t) q_i,     G = Mᵀ R_inᵀ,   B = Mᵀ R_inᵀ A R_in

with g_base = Rot(x, a)·Rot(y, b)·[0, 0, g] = g·[sin b, −cos b sin a, cos b cos a] (the
``table_tilt`` of ``docs/cli-contract.md``). Without the size effect every axis sits at the
lever arm r (q_i = r); with it (``proof_mass_offsets``) each axis has its own q_i
(docs/methods.md §3, the rate-table method). f is linear in g_base and q, and so is its time
derivatives ḟ = Ġ g_base + Ḃ q and f̈, with Ġ, Ḃ, G̈, B̈ precomputed by differentiating G,
B along time (``motion_data.prepare_motion``: Savitzky–Golay derivatives of the encoder angles).

``time_skew``: the sample at t saw the table at t − δ,
f_δ(t) = f(t − δ) ≈ f(t) − δ·ḟ(t) + δ²/2·f̈(t) (second order; with |f⃛| ≲ g·ω³ the neglected
δ³/6·f⃛ is below 1e-6 g for δ ≤ 10 ms at the procedures' rates, ω ≤ 3.5 rad/s).

Sensor (``docs/cli-contract.md``): raw = b + K f_δ + diag(K) ⊙ k2 ⊙ f_δ² / g0.

Parameter vector θ (``ModelSpec.names``): bias (3, channel units), K (9, row-major,
channel unit per m/s²), then the chosen terms in the order of ``TERM_ORDER``: lever_arm
r (3, m) or proof_mass_offsets q (9: q_x, q_y, q_z rows, m), nonlinearity_quadratic k2
(3, 1/g), table_tilt (a, b) (rad), time_skew δ (s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.estimation.motion_data import MotionData, MotionSamples, sample_chunks

FloatArray = npt.NDArray[np.float64]

G0_M_S2 = 9.80665
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
    def needs_rates(self) -> bool:
        """Whether the model reads Ġ, Ḃ, G̈, B̈ (``time_skew``); the others need G and B alone."""
        return "time_skew" in self.terms

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
    theta: FloatArray, m: MotionSamples, spec: ModelSpec, g: float, lever_arm_m: FloatArray
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
    theta: FloatArray, m: MotionData | MotionSamples, spec: ModelSpec, g_m_s2: float, lever_arm_m: FloatArray
) -> FloatArray:
    """(n, 3) specific force f_δ each axis feels (m/s²), lever arm, tilt and skew included.

    Formed :data:`motion_data.PREDICT_CHUNK` samples at a time: each sample's force depends on that sample
    alone, so the chunks bound the (chunk, 3, 3) skew-corrected regressors without changing a bit.
    """
    out = np.empty((m.n, 3))
    for s in sample_chunks(m.n):
        out[s] = _forces(theta, m.take(s, rates=spec.needs_rates), spec, g_m_s2, lever_arm_m)[0]
    return out


def predict(
    theta: FloatArray,
    m: MotionData | MotionSamples,
    spec: ModelSpec,
    g_m_s2: float,
    lever_arm_m: FloatArray,
    *,
    jacobian: bool = False,
) -> tuple[FloatArray, FloatArray | None]:
    """Model raw output (n, 3) and, if asked, ∂raw/∂θ (n, 3, p).

    Without the Jacobian the output is formed :data:`motion_data.PREDICT_CHUNK` samples at a time (each
    sample's prediction depends on that sample alone), so a whole recording's prediction holds
    only (chunk, 3, 3) temporaries; with it, the caller chooses the samples (``MotionData.take``;
    the Jacobian is itself (n, 3, p)).

    :param theta: (p,) parameters in ``spec.names`` order.
    :param lever_arm_m: (3,) lever arm used when the model does not fit it (m).
    """
    if not jacobian:
        out = np.empty((m.n, 3))
        for s in sample_chunks(m.n):
            out[s] = _predict_samples(
                theta, m.take(s, rates=spec.needs_rates), spec, g_m_s2, lever_arm_m, jacobian=False
            )[0]
        return out, None
    ms = m if isinstance(m, MotionSamples) else m.take(slice(0, m.n), rates=spec.needs_rates)
    return _predict_samples(theta, ms, spec, g_m_s2, lever_arm_m, jacobian=True)


def _predict_samples(
    theta: FloatArray,
    m: MotionSamples,
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
