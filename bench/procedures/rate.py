"""rate-1axis: constant-rate steps on the outer (vertical) axis at several fixed poses.

At a constant rate ω about the vertical axis, a sensor at ``p`` (base frame) off the axis
feels the centripetal term ``ω × (ω × p)`` (magnitude ω²·r) on top of gravity, so steps
up to ±200 °/s separate the lever arm from bias and scale (docs/methods.md §3: offsets to
millimetres at up to ±200 °/s). Opposite rates at each pose cancel rate-odd effects (a gyro
scale, time skew) in the sum and isolate them in the difference. The poses turn the sensor
so each of its axes lies in the plane of rotation at least once; ``tilted_deg`` adds the
5–10° tilted poses that separate the per-axis proof-mass offsets (size effect).

Each pose starts with a short static reference window (``Dwell``), then one ``Rotate``
window per rate. Axes as in ``docs/recording-format.md`` (1 = outer, vertical).
"""

from __future__ import annotations

from bench.procedures.steps import Dwell, MoveTo, NoiseWindow, Procedure, Rotate, Step

NAME = "rate-1axis"
DEFAULT_RATES_DEG_S = (50.0, -50.0, 100.0, -100.0, 200.0, -200.0)
# (middle, inner): each sensor axis once up and once down (z up, z down, then x and y both
# ways), so gravity separates bias from scale on every channel and the quadratic
# nonlinearity is determined; with each axis up only, bias is bounded to about 0.9 mg and
# scale to 1.5e-3 (Fisher information of the dynamic model, bench/estimation/observability.py).
DEFAULT_POSES_DEG = ((0.0, 0.0), (180.0, 0.0), (90.0, 90.0), (90.0, -90.0), (90.0, 0.0), (90.0, 180.0))
RATE_AXIS = 1


def rate_1axis(
    dwell_s: float | None = None,
    rates_deg_s: tuple[float, ...] = DEFAULT_RATES_DEG_S,
    window_s: float = 10.0,
    poses_deg: tuple[tuple[float, float], ...] = DEFAULT_POSES_DEG,
    tilted_deg: float = 0.0,
    noise_window_s: float = 60.0,
    spinup_s: float = 3.0,
    settle_s: float = 2.0,
) -> Procedure:
    """Build the rate-1axis procedure.

    :param dwell_s: static reference window per pose (s); ``None``: a noise window first and
        the dwell policy decides (the reference windows then take that dwell).
    :param rates_deg_s: the rates of the outer axis (deg/s), each |rate| <= the table limit.
    :param window_s: recorded window at each rate (s).
    :param poses_deg: (middle, inner) angle pairs (deg).
    :param tilted_deg: when non-zero, each pose is repeated with the middle axis tilted by this
        much (deg), for the size effect.
    :param noise_window_s: noise window when ``dwell_s`` is ``None`` (s).
    :param spinup_s: allowance to reach each rate (s).
    :param settle_s: settling after each move (s).
    """
    if not rates_deg_s:
        raise ValueError("rate-1axis: rates_deg_s is empty")
    poses = list(poses_deg)
    if tilted_deg:
        poses += [(m + tilted_deg, i) for m, i in poses_deg]
    steps: list[Step] = []
    for p, (middle, inner) in enumerate(poses):
        pose_label = f"pose{p + 1}"
        steps.append(MoveTo((0.0, middle, inner), label=pose_label, settle_s=settle_s))
        if p == 0 and dwell_s is None:
            steps.append(NoiseWindow(noise_window_s))
        steps.append(Dwell(f"{pose_label}-static", duration_s=dwell_s))
        for rate in rates_deg_s:
            steps.append(
                Rotate(RATE_AXIS, rate, window_s, label=f"{pose_label}-rate{rate:+g}", spinup_s=spinup_s)
            )
            steps.append(MoveTo((0.0, middle, inner), label=pose_label, settle_s=settle_s))
    params: dict[str, object] = {
        "dwell_s": dwell_s,
        "rates_deg_s": list(rates_deg_s),
        "window_s": window_s,
        "poses_deg": [list(p) for p in poses],
        "tilted_deg": tilted_deg,
        "spinup_s": spinup_s,
        "settle_s": settle_s,
        "noise_window_s": noise_window_s if dwell_s is None else None,
    }
    return Procedure(NAME, tuple(steps), params, n_axes=3)
