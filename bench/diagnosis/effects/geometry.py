"""Effects of where the unit truly was: base tilt, encoder zero offsets, per-window pose errors.

All act on the specific force, so on every channel through K: a window mean changes by
K · ∂f_w/∂p · p to first order in the (small) angles p. With R_w the sensor -> base
attitude from the encoders and g the local gravity:

    table_tilt      g_base = Rot(x, a)·Rot(y, b)·[0, 0, g]   ⇒ ∂f_w/∂(a, b) = R_wᵀ [(0, −g, 0), (g, 0, 0)]
    encoder_offset  θ_true = θ_enc + o                       ⇒ ∂f_w/∂o_j   = ∂(R(θ)ᵀ g e_z)/∂θ_j  (per degree)
    pose_error      g_base = P_wᵀ [0, 0, g], P_w = Rot(x, a_w)·Rot(y, b_w)
                                                             ⇒ ∂f_w/∂(a_w, b_w) = R_wᵀ [(0, g, 0), (−g, 0, 0)]

(signs as in the truth model, ``docs/physics-model.md``). Tilt and offsets are fixed
parameters (``columns``); the 2m pose angles outnumber what 3m window means can carry
beside bias and K, so the pose error is a random effect with variance σ_p² per angle
(``variance``), and each window's angles are reported as their best linear prediction
E[p_w | data] with its posterior standard deviation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.diagnosis.effects.base import Candidate, EffectKind, FloatArray, ParamSpec
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.kinematics import attitude, static_specific_force


def _per_window(K: FloatArray, R: FloatArray, base_vectors: FloatArray) -> FloatArray:
    """(m, 3, q): K · R_wᵀ · v for each base vector v (q, 3)."""
    d = np.einsum("wji,qj->wiq", R, base_vectors)  # R_wᵀ v
    return np.asarray(np.einsum("ik,wkq->wiq", K, d), dtype=float)


def _stack(J: FloatArray) -> FloatArray:
    """(m, 3, q) -> (3m, q) window-major."""
    return J.reshape(-1, J.shape[2])


@dataclass(frozen=True)
class TableTilt:
    """``table_tilt``: the base is not level."""

    id: str = "table_tilt"
    kind: EffectKind = "columns"
    needs_table: bool = True
    parameters: tuple[ParamSpec, ...] = (ParamSpec("tilt_rad", "rad", (2,)),)
    explanation: str = (
        "the table's base is not level, so gravity is not along the base z axis; it shows as "
        "a pose-dependent error that changes when the outer (vertical) axis turns the fixture"
    )

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        if not ev.orientation_known or ev.attitudes() is None:
            return False, "needs table encoders: the recording has no table"
        assert ev.table_rad is not None
        outer = np.unique(np.round(np.rad2deg(ev.table_rad[:, 0]) % 360.0, 1)).size
        if outer < 2:
            return False, "needs windows at several outer-axis angles; all windows share one"
        return True, f"windows at {outer} outer-axis angles"

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        g = ev.g_local_m_s2
        vecs = np.array([[0.0, -g, 0.0], [g, 0.0, 0.0]])

        def cols(e: StaticEvidence, K: FloatArray) -> FloatArray:
            R = e.attitudes()
            assert R is not None
            return _stack(_per_window(K, R, vecs))

        def params(
            theta: FloatArray, cov: FloatArray, K: FloatArray
        ) -> tuple[dict[str, Any], dict[str, Any]]:
            s = np.sqrt(np.clip(np.diag(cov), 0, None))
            return {"tilt_rad": theta.tolist()}, {"tilt_rad": s.tolist()}

        return [Candidate(self.id, self.id, (0, 1, 2), cols, ("tilt_a", "tilt_b"), params)]


@dataclass(frozen=True)
class EncoderOffset:
    """``encoder_offset``: an axis's encoder zero is not its true zero."""

    id: str = "encoder_offset"
    kind: EffectKind = "columns"
    needs_table: bool = True
    parameters: tuple[ParamSpec, ...] = (ParamSpec("offset_deg", "deg", (-1,)),)
    explanation: str = (
        "an encoder's zero is not the axis's true zero, so every pose is off by a fixed angle "
        "about that axis; an offset of the vertical outer axis or of the innermost axis cannot be "
        "told from the unit's own orientation on the fixture"
    )

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        if not ev.orientation_known or ev.table_rad is None:
            return False, "needs table encoders: the recording has no table"
        return True, "checked per axis against the pose set"

    def jacobian(self, ev: StaticEvidence, K: FloatArray, step_deg: float) -> FloatArray:
        """(3m, k) response of the window means to a 1° offset of each axis (central
        differences of step ``step_deg``)."""
        assert ev.table_rad is not None and ev.axis_vectors is not None
        M = np.eye(3) if ev.mount is None else ev.mount
        h = np.deg2rad(step_deg)
        cols = []
        for j in range(ev.table_rad.shape[1]):
            dq = np.zeros(ev.table_rad.shape[1])
            dq[j] = h
            fp = static_specific_force(attitude(ev.axis_vectors, ev.table_rad + dq, M), ev.g_local_m_s2)
            fm = static_specific_force(attitude(ev.axis_vectors, ev.table_rad - dq, M), ev.g_local_m_s2)
            df = (fp - fm) / (2 * step_deg)  # per degree
            cols.append((df @ K.T).reshape(-1))
        return np.stack(cols, axis=1)

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        assert ev.table_rad is not None
        k = ev.table_rad.shape[1]
        out = []
        for j in range(k):

            def cols(e: StaticEvidence, K: FloatArray, j: int = j) -> FloatArray:
                return self.jacobian(e, K, th.encoder_step_deg)[:, j : j + 1]

            def params(
                theta: FloatArray, cov: FloatArray, K: FloatArray, j: int = j
            ) -> tuple[dict[str, Any], dict[str, Any]]:
                v, s = [0.0] * k, [0.0] * k
                v[j], s[j] = float(theta[0]), float(np.sqrt(max(cov[0, 0], 0.0)))
                return {"offset_deg": v}, {"offset_deg": s}

            out.append(
                Candidate(self.id, f"{self.id}[axis {j + 1}]", (0, 1, 2), cols, (f"offset_deg[{j}]",), params)
            )
        return out


def pose_response(ev: StaticEvidence, K: FloatArray) -> FloatArray:
    """(m, 3, 2) response J_w of each window mean to its two pose angles (rad).

    With the table's attitudes, the angles are about the base x and y axes (truth-model
    convention); without a table (hand-held, labelled poses) about two sensor-frame axes
    perpendicular to the window's gravity direction, u1 = normalise(e × f̂) for the sensor
    axis e least aligned with f̂, u2 = f̂ × u1, so that J_w = K · g [u1 u2].
    """
    R = ev.attitudes() if ev.orientation_known else None
    g = ev.g_local_m_s2
    if R is not None:
        return _per_window(K, R, np.array([[0.0, g, 0.0], [-g, 0.0, 0.0]]))
    f = ev.f_m_s2
    fh = f / np.linalg.norm(f, axis=1, keepdims=True)
    e = np.eye(3)[np.argmin(np.abs(fh), axis=1)]
    u1 = np.cross(e, fh)
    u1 /= np.linalg.norm(u1, axis=1, keepdims=True)
    u2 = np.cross(fh, u1)
    d = g * np.stack([u1, u2], axis=2)  # (m, 3, 2)
    return np.asarray(np.einsum("ik,wkq->wiq", K, d), dtype=float)


@dataclass(frozen=True)
class PoseError:
    """``pose_error``: the unit was not where the recording says in some windows."""

    id: str = "pose_error"
    kind: EffectKind = "variance"
    needs_table: bool = False
    parameters: tuple[ParamSpec, ...] = (ParamSpec("angles_rad", "rad", (-1, 2)),)
    explanation: str = (
        "the unit was not where the recording says (hand placement, a loose fixture): each "
        "window's gravity direction is off by a small, different angle, so the window means "
        "scatter perpendicular to gravity, on all channels together"
    )

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        if not ev.orientation_known:
            return False, "the recording does not say where the unit was, so there is nothing to be off from"
        if ev.m < 6:
            return False, f"needs at least 6 windows to tell pose scatter from noise, got {ev.m}"
        return True, f"{ev.m} windows, 3 channels each"

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        return []


TILT = TableTilt()
ENCODER_OFFSET = EncoderOffset()
POSE_ERROR = PoseError()
