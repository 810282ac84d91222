"""static-12: the tumble test on a three-axis table, twelve well-spread orientations.

The sensor's gravity direction visits the twelve vertices of a regular icosahedron, the
most uniform spread of twelve directions on the sphere (every axis sees +g, -g and the
in-between values, and the design is rotation-invariant, so no parameter of the first-order
model ``raw = b + K·f`` is identified worse than another). The outer axis is stepped
through 0°, 90°, 180°, 270° from pose to pose: on a level table it does not change what the
sensor feels, but it turns a tilted base's gravity error with it, which makes the tilt
(effect ``table_tilt``) observable and keeps it out of the bias.

Order in time: antipodal vertices are visited one after the other (:data:`EXECUTION_ORDER`),
so a slowly wandering bias adds nearly the same value to +u and −u and goes into the bias
estimate, not into K (K is read from the difference of antipodes). Of the 6!·2⁶ orders of
adjacent antipodal pairs, this one leaks least of a linear and a quadratic trend in time into
K: a bias ramp over the run moves the least-squares K by 0.056 of the ramp's end-to-end change
/ g (Frobenius norm over the 9 elements; quadratic 0.028), where the icosahedron's ring order
(+z first, −z last) moved it by 1.06 (quadratic 0.18).

Poses assume the default geometry of ``docs/recording-format.md``: outer axis ``z``, middle axis
``x``, inner axis ``z`` (at zero middle angle). With ``R = Rz(θ1)·Rx(θ2)·Rz(θ3)`` the
specific force at rest is ``f = Rᵀ·[0, 0, g] = g·(sin θ2 sin θ3, sin θ2 cos θ3, cos θ2)``,
so a wanted up-direction ``u`` in the sensor frame needs ``θ2 = acos(u_z)``,
``θ3 = atan2(u_x, u_y)``.

Source of the method: docs/methods.md §1 (static 12-orientation calibration, dwell from Allan).
"""

from __future__ import annotations

import math

import numpy as np

from bench.procedures.steps import Dwell, MoveTo, NoiseWindow, Procedure, Step

NAME = "static-12"
OUTER_ANGLES_DEG = (0.0, 90.0, 180.0, -90.0)
DEFAULT_NOISE_WINDOW_S = 120.0
EXECUTION_ORDER = (0, 11, 7, 5, 8, 1, 10, 3, 4, 6, 2, 9)
"""Indices into :func:`icosahedron_up_directions` in the order the poses are visited."""


def icosahedron_up_directions() -> np.ndarray:
    """(12, 3) unit vectors: the icosahedron's vertices, top first, ring by ring.

    Polar angles 0, atan(2) (five, azimuths 0°, 72°, …), π − atan(2) (five, azimuths 36°,
    108°, …) and π.
    """
    polar = math.atan(2.0)
    dirs = [(0.0, 0.0, 1.0)]
    for ring_polar, az0 in ((polar, 0.0), (math.pi - polar, 36.0)):
        for k in range(5):
            az = math.radians(az0 + 72.0 * k)
            dirs.append(
                (
                    math.sin(ring_polar) * math.sin(az),
                    math.sin(ring_polar) * math.cos(az),
                    math.cos(ring_polar),
                )
            )
    dirs.append((0.0, 0.0, -1.0))
    return np.array(dirs)


def pose_for_up(up: np.ndarray, outer_deg: float) -> tuple[float, float, float]:
    """Table angles (deg) that put the sensor-frame unit vector ``up`` along base ``+z``.

    :param up: (3,) unit vector in the sensor frame.
    :param outer_deg: outer-axis angle (free on a level table).
    """
    theta2 = math.degrees(math.acos(max(-1.0, min(1.0, float(up[2])))))
    theta3 = math.degrees(math.atan2(float(up[0]), float(up[1]))) if abs(up[2]) < 1 - 1e-12 else 0.0
    return (outer_deg, round(theta2, 6), round(theta3, 6))


def static_12_poses_deg() -> list[tuple[float, float, float]]:
    """The twelve (outer, middle, inner) poses in degrees, in execution order (:data:`EXECUTION_ORDER`)."""
    dirs = icosahedron_up_directions()[list(EXECUTION_ORDER)]
    return [pose_for_up(d, OUTER_ANGLES_DEG[i % len(OUTER_ANGLES_DEG)]) for i, d in enumerate(dirs)]


def static_12(
    dwell_s: float | None = None, noise_window_s: float = DEFAULT_NOISE_WINDOW_S, settle_s: float = 2.0
) -> Procedure:
    """Build the static-12 procedure.

    :param dwell_s: static dwell per pose (s). ``None``: the procedure first records a noise
        window of ``noise_window_s`` at the first pose and the run's dwell policy derives
        the dwell from it.
    :param noise_window_s: length of that noise window (s).
    :param settle_s: settling allowance after each move (s).
    """
    poses = static_12_poses_deg()
    steps: list[Step] = []
    for i, pose in enumerate(poses):
        label = f"pos{i + 1:02d}"
        steps.append(MoveTo(pose, label=label, settle_s=settle_s))
        if i == 0 and dwell_s is None:
            steps.append(NoiseWindow(noise_window_s))
        steps.append(Dwell(label, duration_s=dwell_s))
    params: dict[str, object] = {
        "dwell_s": dwell_s,
        "settle_s": settle_s,
        "noise_window_s": noise_window_s if dwell_s is None else None,
    }
    return Procedure(NAME, tuple(steps), params, n_axes=3)
