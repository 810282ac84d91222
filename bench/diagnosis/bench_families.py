"""The bench-physics stage after a diagnosis's model is chosen: what the final model leaves,
searched for physics that is no function of the specific force, temperature or time alone.

- Static recordings: periodic lines in the windows' samples (``periodic_lines``).
- Moving recordings: disturbances locked to a table axis's angle, a delay that grows along
  the run, periodic lines in the final residual (``motion_families``).

Each is reported as a finding with its own effect id (docs/diagnose.md, "Bench physics
beyond the catalogue"); it does not change the model the catalogue and library chose, nor
``calibrate``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from dataclasses import replace as dc_replace

import numpy as np

from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.family_referee import head_to_head, kfdot
from bench.diagnosis.motion_families import ClockDrift, Families, Harmonic, find_families
from bench.diagnosis.periodic_lines import Line, find_periodic_lines, residual_stretches, without_lines
from bench.diagnosis.result import Diagnosis, Finding
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit
from bench.estimation.dynamic_model import predict, specific_force
from bench.estimation.motion_data import MotionData

FloatArray = np.ndarray
CHANNELS = ("ax", "ay", "az")
FINDING_PARAMETERS: dict[str, tuple[str, ...]] = {
    "periodic_line": ("frequency_hz", "amplitude", "phase_rad", "channels"),
    "angle_harmonic": ("axis", "harmonic", "amplitude", "phase_rad", "channels"),
    "clock_drift": ("delay_s_per_s",),
}
"""The findings this stage reports beside the catalogue: effect id -> parameter names
(docs/cli-contract.md, "Effect ids and their parameters")."""
LINE_EXPLANATION = (
    "a vibration, mains pick-up or a pump reaching the sensor: a sinusoid at one frequency "
    "on the samples, locked to time, not to the table's motion"
)
HARMONIC_EXPLANATION = (
    "a disturbance locked to a table axis's angle (a motor's magnetic field, a cable's pull, "
    "a slip ring's once-per-turn): it repeats with the axis's turn, not with time"
)
DRIFT_EXPLANATION = (
    "the DAQ's clock and the encoders' run at slightly different rates, so the delay between "
    "a sample and its encoder reading grows along the run"
)


def _line_finding(line: Line, channel_unit: str, n: int, rms_after: float) -> Finding:
    z2 = float(np.max((line.amplitude / np.maximum(line.amplitude_sigma, 1e-300))[list(line.channels)]) ** 2)
    return Finding(
        effect="periodic_line",
        summary=line.summary(channel_unit),
        parameters={
            "frequency_hz": line.frequency_hz,
            "amplitude": line.amplitude.tolist(),
            "phase_rad": line.phase_rad.tolist(),
            "channels": [CHANNELS[i] for i in line.channels],
        },
        sigma={"frequency_hz": line.frequency_sigma_hz, "amplitude": line.amplitude_sigma.tolist()},
        delta_bic=float(-z2 + 3.0 * math.log(max(n, 2))),
        lr=z2,
        residual_rms_after=rms_after,
        explanation=LINE_EXPLANATION,
    )


def static_lines(
    ev: StaticEvidence, th: Thresholds = THRESHOLDS
) -> tuple[tuple[Line, ...], tuple[FloatArray, ...] | None]:
    """Periodic lines in a static recording's window samples, and the samples without them (for
    the within-window tests: a line is not a ring after a move), or ``None`` when there are none."""
    if ev.window_samples is None or ev.window_t_s is None or ev.sample_rate_hz is None:
        return (), ev.window_samples
    pieces = list(zip(ev.window_t_s, ev.window_samples, strict=True))
    lines = find_periodic_lines(pieces, ev.sample_rate_hz, th)
    return lines, (without_lines(pieces, lines) if lines else ev.window_samples)


def static_line_findings(
    ev: StaticEvidence, lines: tuple[Line, ...], channel_unit: str, rms_after: float
) -> list[Finding]:
    """The lines of :func:`static_lines` as findings."""
    n = 0 if ev.window_t_s is None else int(sum(t.size for t in ev.window_t_s))
    return [_line_finding(ln, channel_unit, n, rms_after) for ln in lines]


def harmonic_findings(hs: tuple[Harmonic, ...], left: FloatArray, channel_unit: str) -> list[Finding]:
    """One finding per (axis, harmonic); ``left`` (n, 3) the residual without them."""
    n = left.shape[0]
    out = []
    for h in hs:
        parts = ", ".join(
            f"{CHANNELS[i]} {h.amplitude[i]:.3g} ± {h.amplitude_sigma[i]:.2g} {channel_unit}"
            for i in h.channels
        )
        out.append(
            Finding(
                effect="angle_harmonic",
                summary=(
                    f"a disturbance locked to axis {h.axis + 1}'s angle, {h.harmonic} per turn: {parts} "
                    "(peak); it follows the axis's angle, not time (a motor's field, a cable, a slip ring)"
                ),
                parameters={
                    "axis": h.axis + 1,
                    "harmonic": h.harmonic,
                    "amplitude": h.amplitude.tolist(),
                    "phase_rad": h.phase_rad.tolist(),
                    "channels": [CHANNELS[i] for i in h.channels],
                },
                sigma={"amplitude": h.amplitude_sigma.tolist()},
                delta_bic=float(-2.0 * h.f_stat + 2.0 * math.log(max(n, 2))),
                lr=float(2.0 * h.f_stat),
                residual_rms_after=float(np.sqrt(np.mean(left**2))),
                explanation=HARMONIC_EXPLANATION,
            )
        )
    return out


def drift_finding(cd: ClockDrift, span_s: float, left: FloatArray) -> Finding:
    """The ``clock_drift`` finding of a growth ``cd`` over a run of ``span_s``; ``left`` (n, 3) the
    residual without the families."""
    n = left.shape[0]
    return Finding(
        effect="clock_drift",
        summary=(
            "the delay between the DAQ's samples and the encoders grows by "
            f"{cd.rate_s_per_s:.3g} ± {cd.sigma:.2g} s per s ({cd.rate_s_per_s * 1e6:.3g} ppm; "
            f"{cd.rate_s_per_s * span_s * 1e3:.3g} ms over the {span_s:.0f} s): two clocks drifting; "
            "a time_skew found beside it is the mean delay"
        ),
        parameters={"delay_s_per_s": cd.rate_s_per_s},
        sigma={"delay_s_per_s": cd.sigma},
        delta_bic=float(-cd.wald + math.log(max(n, 2))),
        lr=cd.wald,
        residual_rms_after=float(np.sqrt(np.mean(left**2))),
        explanation=DRIFT_EXPLANATION,
    )


def family_findings(fam: Families, left: FloatArray, span_s: float, channel_unit: str) -> list[Finding]:
    """The harmonics and the growth of ``fam`` as findings; ``left`` (n, 3) the residual without them."""
    out = harmonic_findings(fam.harmonics, left, channel_unit)
    return out + ([drift_finding(fam.drift, span_s, left)] if fam.drift is not None else [])


def moving_families(
    t_s: FloatArray,
    r: FloatArray,
    f_m_s2: FloatArray,
    K: FloatArray,
    angles_rad: FloatArray,
    valid: FloatArray,
    th: Thresholds = THRESHOLDS,
) -> tuple[Families, FloatArray, FloatArray]:
    """Angle harmonics and clock drift in a moving recording's residual, the used samples' mask
    (n,) and their residual without the families (n_used, 3).

    :param t_s: (n,) time (s); :param r: (n, 3) the model's residual (channel units).
    :param f_m_s2: (n, 3) the model's specific force (m/s²); :param K: (3, 3) its scale matrix.
    :param angles_rad: (n, k) unwrapped encoder angles; :param valid: (n,) samples the fit used.
    """
    ok = np.asarray(valid, dtype=bool) & np.all(np.isfinite(r), axis=1)
    kf = kfdot(f_m_s2[ok], K, t_s[ok])
    fam = find_families(r[ok], f_m_s2[ok], kf, angles_rad[ok], t_s[ok], th)
    return fam, ok, r[ok] - fam.signal(angles_rad[ok], kf, t_s[ok])


def moving_findings(
    t_s: FloatArray,
    r: FloatArray,
    f_m_s2: FloatArray,
    K: FloatArray,
    angles_rad: FloatArray,
    valid: FloatArray,
    sample_rate_hz: float,
    channel_unit: str,
    th: Thresholds = THRESHOLDS,
) -> tuple[list[Finding], Families, FloatArray]:
    """Angle harmonics, clock drift and periodic lines in a moving recording's final residual,
    the families found and the residual without them (n_used, 3). Arguments as
    :func:`moving_families`, ``sample_rate_hz`` (Hz) for the lines."""
    fam, ok, left = moving_families(t_s, r, f_m_s2, K, angles_rad, valid, th)
    t = t_s[ok]
    out = family_findings(fam, left, float(t[-1] - t[0]), channel_unit)
    stretches = residual_stretches(t, left, np.ones(t.size, dtype=bool), th.line_block_s)
    lines = find_periodic_lines(stretches, sample_rate_hz, th)
    rms = float(np.sqrt(np.mean(left**2)))
    out += [_line_finding(ln, channel_unit, t.size, rms) for ln in lines]
    return out, fam, left


@dataclass(frozen=True)
class MovingSearch:
    """The bench families on a moving recording's final residual (:func:`moving_search`).

    :param findings: the angle harmonics, the clock drift and the periodic lines as findings.
    :param families: the harmonics and the growth found; :param left: (n_used, 3) the final
        residual without them.
    :param residual: (n, 3) the final model's residual, the discovered terms taken out
        (channel units); :param f_m_s2: (n, 3) its specific force (m/s²); :param K: (3, 3) its
        scale matrix.
    """

    findings: tuple[Finding, ...]
    families: Families
    left: FloatArray
    residual: FloatArray
    f_m_s2: FloatArray
    K: FloatArray


def moving_search(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever: FloatArray,
    final: DynamicFit,
    library: FloatArray | None,
    channel_unit: str,
    th: Thresholds = THRESHOLDS,
) -> MovingSearch:
    """:func:`moving_findings` on the final dynamic model's residual.

    :param final: the final fit; :param library: (n, 3) the discovered terms' contribution
        (channel units) or ``None``.
    """
    model, _ = predict(final.theta, m, final.spec, g_m_s2, lever)
    r = y - model - (0.0 if library is None else library)
    f = specific_force(final.theta, m, final.spec, g_m_s2, lever)
    K = final.theta[3:12].reshape(3, 3)
    found, fam, full_left = moving_findings(
        m.t_s, r, f, K, m.angles_rad, m.valid, 1.0 / m.step_s, channel_unit, th
    )
    return MovingSearch(tuple(found), fam, full_left, r, f, K)


def moving_head_to_head(
    m: MotionData,
    y: FloatArray,
    g_m_s2: float,
    lever: FloatArray,
    search: MovingSearch,
    library: FloatArray | None,
    channel_unit: str,
    th: Thresholds = THRESHOLDS,
    *,
    baseline: DynamicFit,
    n_params: int,
    rerun: Callable[[FloatArray, frozenset[str]], Diagnosis | None],
) -> Diagnosis | None:
    """Where a family is left in the final residual (``search``) or in the catalogue's (the
    discovered terms added back: library terms can take a family whole), the head to head of
    ``family_referee``: the alternative diagnosis when it wins, else ``None``.

    :param library: (n, 3) the discovered terms' contribution (channel units) or ``None``.
    :param baseline: the first-order fit; :param n_params: the claimed model's parameters
        beyond bias and K (catalogue terms' and discovered terms').
    :param rerun: (samples, the catalogue terms the alternative may claim) -> their diagnosis
        without the head to head, or ``None`` once it cannot win (``family_referee.head_to_head``).
    """
    fam = search.families
    if fam.empty and (
        library is None
        or moving_families(
            m.t_s, search.residual + library, search.f_m_s2, search.K, m.angles_rad, m.valid, th
        )[0].empty
    ):
        return None
    k_full = n_params + fam.n_params
    won = head_to_head(m, y, g_m_s2, lever, baseline, search.left, k_full, rerun, th)
    if won is None:
        return None
    alt, fam_alt, left_alt, note = won
    ok = np.asarray(m.valid, dtype=bool)
    span = float(np.ptp(m.t_s[ok])) if ok.any() else 0.0
    alt_findings = (*family_findings(fam_alt, left_alt, span, channel_unit), *alt.findings)
    return dc_replace(alt, findings=alt_findings, notes=(note, *alt.notes))


__all__ = [
    "MovingSearch",
    "moving_families",
    "moving_findings",
    "moving_head_to_head",
    "moving_search",
    "static_line_findings",
    "static_lines",
]
