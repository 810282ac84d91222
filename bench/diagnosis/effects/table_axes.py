"""``table_axis_error``: a gimbal axis of the table is not where the table's drawing says.

The bench's physics, not the unit's. Axis j turns about u'_j = Rot(e2_j, b_j)·Rot(e1_j, a_j)·u_j
(its parent frame) instead of the nominal u_j, with e1_j = normalise(u_j × c_j), c_j the
coordinate vector least aligned with u_j (the first on ties), and e2_j = u_j × e1_j (the
simulator's convention, docs/physics-model.md). To first order a window mean moves by
K·∂f_w/∂(a_j, b_j)·(a_j, b_j), f_w = R_wᵀ·[0, 0, g] with R_w = attitude(u', θ_w, M): one
column per (axis, angle), taken by central differences of ``bench.kinematics.attitude``.

What a static pose set can tell (default table: outer z, middle x, inner z): the middle
axis turned towards the outer axis (angle b of axis 2: off perpendicular) and the inner
axis turned towards the middle one (angle a of axis 3) are new signatures; the outer axis's
two angles act like the base's tilt (``table_tilt``: an outer axis that is not vertical);
the middle axis turned about the outer axis is an outer encoder offset plus a turn of the
unit on its mount (bias and K absorb it), and the inner axis turned about the middle one is
a middle encoder offset plus a mount turn. Columns that bias and K absorb are left out by the
selection's leverage rule; look-alikes (|cos| > 0.8 beyond the model) are named in the
finding (``confounding``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.diagnosis.effects.base import Candidate, EffectKind, FloatArray, ParamSpec
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.kinematics import attitude, static_specific_force


def error_directions(u: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(e1, e2): the directions (3,) about which axis u (3,) is turned by its two angles."""
    c = np.eye(3)[int(np.argmin(np.abs(u)))]
    e1 = np.cross(u, c)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


def _turned(u: FloatArray, e: FloatArray, angle_rad: float) -> FloatArray:
    """Rodrigues: u turned by angle about the unit vector e."""
    return np.asarray(
        u * np.cos(angle_rad) + np.cross(e, u) * np.sin(angle_rad) + e * (e @ u) * (1 - np.cos(angle_rad)),
        dtype=float,
    )


def axis_response(
    ev: StaticEvidence, K: FloatArray, axis: int, angle: int, step_rad: float = THRESHOLDS.table_axis_step_rad
) -> FloatArray:
    """(3m,) response of the stacked window means to 1 rad of ``angle`` (0: a, 1: b) of ``axis``
    (central differences of step ``step_rad``)."""
    assert ev.table_rad is not None and ev.axis_vectors is not None
    M = np.eye(3) if ev.mount is None else ev.mount
    u = ev.axis_vectors[axis]
    e = error_directions(u)[angle]
    out = []
    for h in (step_rad, -step_rad):
        axes = np.array(ev.axis_vectors, dtype=float, copy=True)
        axes[axis] = _turned(u, e, h)
        out.append(static_specific_force(attitude(axes, ev.table_rad, M), ev.g_local_m_s2))
    df = (out[0] - out[1]) / (2 * step_rad)
    return np.asarray((df @ K.T).reshape(-1), dtype=float)


@dataclass(frozen=True)
class TableAxisError:
    """``table_axis_error``: a table axis's direction is off by two small angles (module docstring)."""

    id: str = "table_axis_error"
    kind: EffectKind = "columns"
    needs_table: bool = True
    parameters: tuple[ParamSpec, ...] = (ParamSpec("angles_rad", "rad", (-1, 2)),)
    explanation: str = (
        "a gimbal axis of the table is not where the table's geometry says (e.g. the middle axis "
        "not perpendicular to the outer one): the bench's physics, not the unit's; each pose's "
        "gravity direction is off by an amount that follows the axes' angles"
    )

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        if not ev.orientation_known or ev.table_rad is None or ev.axis_vectors is None:
            return False, "needs table encoders: the recording has no table"
        if ev.table_rad.shape[1] < 2:
            return False, "a one-axis table's axis direction is the base's tilt (table_tilt)"
        return True, "checked per axis (two angles each) against the pose set"

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        assert ev.table_rad is not None
        k = ev.table_rad.shape[1]
        out = []
        # the outermost axis's direction relative to gravity is the base's tilt (table_tilt)
        for j in range(1, k):
            for a in range(2):

                def cols(e: StaticEvidence, K: FloatArray, j: int = j, a: int = a) -> FloatArray:
                    return axis_response(e, K, j, a, th.table_axis_step_rad)[:, None]

                def params(
                    theta: FloatArray, cov: FloatArray, K: FloatArray, j: int = j, a: int = a
                ) -> tuple[dict[str, Any], dict[str, Any]]:
                    v = [[0.0, 0.0] for _ in range(k)]
                    s = [[0.0, 0.0] for _ in range(k)]
                    v[j][a], s[j][a] = float(theta[0]), float(np.sqrt(max(cov[0, 0], 0.0)))
                    return {"angles_rad": v}, {"angles_rad": s}

                out.append(
                    Candidate(
                        self.id,
                        f"{self.id}[axis {j + 1}, {'ab'[a]}]",
                        (0, 1, 2),
                        cols,
                        (f"angles_rad[{j}][{a}]",),
                        params,
                    )
                )
        return out


TABLE_AXIS_ERROR = TableAxisError()
