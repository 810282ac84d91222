"""planned-static: the static design the planner (``bench.planning``) chooses, as a procedure.

The twelve icosahedron directions of static-12 (:func:`~bench.procedures.static.icosahedron_up_directions`)
in its antipodal execution order, visited ``repeats`` times with a short ``dwell_s`` each: a
pass forwards, the next backwards (antipodes stay adjacent in time and a linear drift over two
passes cancels), the outer axis stepping 0°, 90°, 180°, −90° from visit to visit so a tilted base
stays separable. Every window is an ordinary static window (labels ``p001``, ``p002``, …) and the
recording is calibrated by the static window fit (``bench.estimation.static_fit``) with its slow
wander between windows — the fit whose covariance the planner predicts.

planned-tumble (:func:`planned_tumble`): the same steps, recorded and calibrated by the
dynamic batch fit of every sample (``bench.calibration.kind.MOVING_PROCEDURES``), so the moves
and the settling count as information (``bench.planning.every_sample``).
"""

from __future__ import annotations

import math

from bench.procedures.static import (
    EXECUTION_ORDER,
    OUTER_ANGLES_DEG,
    icosahedron_up_directions,
    pose_for_up,
)
from bench.procedures.steps import Dwell, MoveTo, Procedure, Step

NAME = "planned-static"
TUMBLE_NAME = "planned-tumble"
DEFAULT_DWELL_S = 10.0
MAX_WINDOWS = 2400


def visit_order(repeats: int) -> list[int]:
    """Icosahedron vertex index of every visit: forward passes alternating with reversed ones."""
    out: list[int] = []
    for r in range(repeats):
        out += list(EXECUTION_ORDER) if r % 2 == 0 else list(reversed(EXECUTION_ORDER))
    return out


def planned_poses_deg(repeats: int) -> list[tuple[float, float, float]]:
    """(outer, middle, inner) of every visit (deg), in order."""
    dirs = icosahedron_up_directions()
    return [
        pose_for_up(dirs[k], OUTER_ANGLES_DEG[i % len(OUTER_ANGLES_DEG)])
        for i, k in enumerate(visit_order(repeats))
    ]


def planned_static(
    dwell_s: float | None = None,
    repeats: float = 1,
    settle_s: float = 2.0,
    predicted_bias_u_ug: float | None = None,
    predicted_scale_u_ppm: float | None = None,
    predicted_misalignment_u_urad: float | None = None,
    *,
    name: str = NAME,
) -> Procedure:
    """Build the planned static procedure (``name``: :data:`NAME` or :data:`TUMBLE_NAME`).

    :param dwell_s: static window per visit (s); ``None`` takes :data:`DEFAULT_DWELL_S` (the
        plan fixes it, so no noise window is recorded).
    :param repeats: passes over the twelve directions, 1..200.
    :param settle_s: settling allowance after each move (s).
    :param predicted_bias_u_ug: the planner's predicted U (k = 2) of the largest bias (µg), stored
        with the run so the certificate can state it beside the achieved one; likewise
        ``predicted_scale_u_ppm`` and ``predicted_misalignment_u_urad``. They change no step.
    :raises ValueError: repeats outside 1..200, or a predicted U that is not a number > 0.
    """
    if repeats != int(repeats):
        raise ValueError(f"{name} repeats must be a whole number, got {repeats}")
    repeats = int(repeats)
    if not 1 <= repeats <= MAX_WINDOWS // 12:
        raise ValueError(f"{name} repeats must be 1..{MAX_WINDOWS // 12}, got {repeats}")
    dwell = DEFAULT_DWELL_S if dwell_s is None else float(dwell_s)
    steps: list[Step] = []
    for i, pose in enumerate(planned_poses_deg(repeats)):
        label = f"p{i + 1:03d}"
        steps.append(MoveTo(pose, label=label, settle_s=settle_s))
        steps.append(Dwell(label, duration_s=dwell))
    params: dict[str, object] = {"dwell_s": dwell, "repeats": repeats, "settle_s": settle_s}
    for key, value in (
        ("predicted_bias_u_ug", predicted_bias_u_ug),
        ("predicted_scale_u_ppm", predicted_scale_u_ppm),
        ("predicted_misalignment_u_urad", predicted_misalignment_u_urad),
    ):
        if value is not None:
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} {key} must be a number > 0, got {value!r}")
            params[key] = float(value)
    return Procedure(name, tuple(steps), params, n_axes=3)


def planned_tumble(
    dwell_s: float | None = None,
    repeats: float = 1,
    settle_s: float = 2.0,
    predicted_bias_u_ug: float | None = None,
    predicted_scale_u_ppm: float | None = None,
    predicted_misalignment_u_urad: float | None = None,
) -> Procedure:
    """planned-tumble: :func:`planned_static`'s steps, fitted by the every-sample fit (module
    docstring); the same parameters and errors."""
    return planned_static(
        dwell_s,
        repeats,
        settle_s,
        predicted_bias_u_ug,
        predicted_scale_u_ppm,
        predicted_misalignment_u_urad,
        name=TUMBLE_NAME,
    )
