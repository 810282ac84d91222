"""oscillation-2axis: quasi-harmonic oscillation of two axes (docs/methods.md §2).

The paper's dynamic calibration oscillates both axes of a two-axis table with amplitudes
360° and 90° and periods ``2·T1 = 5·T2``, ``T2 = 12 s`` (so ``T1 = 30 s``), and reaches in
1.5 minutes the accuracy of a 40-minute static test. On the three-axis table the middle
(horizontal) axis carries the 90° oscillation about 90°, so the sensor's z axis sweeps
from straight up to straight down, and the inner axis carries the 360° oscillation, which
turns x and y through every direction; the outer axis stays still. Peak rates are
2π·360/30 ≈ 75 °/s and 2π·90/12 ≈ 47 °/s, so the centripetal and tangential terms make the
lever arm observable too.

The motion window is framed by two static reference windows (at the centre pose and with
the sensor upside down) that anchor the bias for the estimator.
"""

from __future__ import annotations

from bench.procedures.steps import Dwell, MoveTo, NoiseWindow, Oscillate, Procedure, Step

NAME = "oscillation-2axis"
T2_S = 12.0
T1_S = 2.5 * T2_S
AMPLITUDE_INNER_DEG = 360.0
AMPLITUDE_MIDDLE_DEG = 90.0
CENTRE_DEG = (0.0, 90.0, 0.0)


def oscillation_2axis(
    dwell_s: float | None = None,
    duration_s: float = 90.0,
    noise_window_s: float = 60.0,
    settle_s: float = 2.0,
) -> Procedure:
    """Build the oscillation-2axis procedure.

    :param dwell_s: static reference windows (s); ``None``: noise window first, dwell policy.
    :param duration_s: oscillation window (s), default three periods of the slow axis.
    :param noise_window_s: noise window when ``dwell_s`` is ``None`` (s).
    :param settle_s: settling after each move (s).
    """
    steps: list[Step] = [MoveTo(CENTRE_DEG, label="centre", settle_s=settle_s)]
    if dwell_s is None:
        steps.append(NoiseWindow(noise_window_s))
    steps += [
        Dwell("centre-static", duration_s=dwell_s),
        MoveTo((0.0, 180.0, 0.0), label="down", settle_s=settle_s),
        Dwell("down-static", duration_s=dwell_s),
        MoveTo(CENTRE_DEG, label="centre", settle_s=settle_s),
        Oscillate(
            axes=(3, 2),
            amplitudes_deg=(AMPLITUDE_INNER_DEG, AMPLITUDE_MIDDLE_DEG),
            periods_s=(T1_S, T2_S),
            duration_s=duration_s,
            label="oscillation",
        ),
        MoveTo(CENTRE_DEG, label="centre", settle_s=settle_s),
    ]
    params: dict[str, object] = {
        "dwell_s": dwell_s,
        "duration_s": duration_s,
        "periods_s": [T1_S, T2_S],
        "amplitudes_deg": [AMPLITUDE_INNER_DEG, AMPLITUDE_MIDDLE_DEG],
        "settle_s": settle_s,
        "noise_window_s": noise_window_s if dwell_s is None else None,
    }
    return Procedure(NAME, tuple(steps), params, n_axes=3)
