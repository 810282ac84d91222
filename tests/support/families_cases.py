"""Bench physics nobody listed, concealed by the truth model (``drivers/sim/bench_effects.py``),
and the scoring of a diagnosis against it (docs/diagnose.md, "Bench physics beyond the
catalogue"; ``benchmarks/study_diagnose_families.py``).

A case is one family at one size on one kind of recording: ``static`` (the 12-pose tumble of
``tests.support.diagnose_cases``), ``rate`` or ``oscillation`` (``diagnose_dynamic_cases``).
Typical ADXL-like triad in V, 100 Hz, 250 µg/√Hz, 40 µg wander. Scores:

- ``named``: the family's finding with the truth within 3 sigma (table_axis_error: that
  axis's angle; angle_harmonic: that axis and harmonic, the amplitude on the truth's channel;
  periodic_line: the frequency and the amplitude on its channel; clock_drift: the rate;
  hysteresis: that axis's half step on its channel), or ``unexplained`` naming the right
  channel (and, for hysteresis, the direction of the last move);
- ``claimed``: a catalogue finding (the contract's ids) or a discovered term for physics
  the recording does not contain (time_skew beside a clock drift is its mean delay, allowed).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from api.simulated_recording import to_recording
from bench.diagnosis import Diagnosis
from bench.diagnosis.effects import CATALOGUE
from bench.recording import Recording
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth
from tests.support.diagnose_cases import static_recording
from tests.support.diagnose_dynamic_cases import moving_recording

G0 = 9.80665
CATALOGUE_IDS = frozenset(e.id for e in CATALOGUE)
CHANNELS = ("ax", "ay", "az")


@dataclass(frozen=True)
class FamilyCase:
    """One family at one size.

    :param name: row label; :param kind: ``static``, ``rate`` or ``oscillation``.
    :param effects: (size) -> the truth model's effects; :param size: the size (``unit``).
    :param channel: the channel the truth acts on (0, 1, 2).
    :param score: (diagnosis, truth) -> (named, |z| or NaN).
    :param allowed: catalogue ids that are part of the truth's physics.
    """

    name: str
    kind: str
    size: float
    unit: str
    effects: Callable[[float], dict[str, dict[str, Any]]]
    channel: int
    score: Callable[[Diagnosis, SensorTruth, float], tuple[bool, float]]
    allowed: frozenset[str] = frozenset()

    def recording(self, seed: int) -> Recording:
        eff = self.effects(self.size)
        if self.kind == "static":
            return static_recording(eff, seed)
        return moving_recording(eff, seed, self.kind)

    def truth(self, seed: int) -> SensorTruth:
        return SensorTruth.typical("V", seed=seed)

    def claimed(self, d: Diagnosis) -> list[str]:
        """Catalogue findings and discovered terms the truth does not hold."""
        out = [f.effect for f in d.findings if f.effect in CATALOGUE_IDS and f.effect not in self.allowed]
        return out + [f"{x.term}[{x.channel}]" for x in d.discovered]


def _unexplained_on(d: Diagnosis, ch: int, words: str = "") -> bool:
    u = d.unexplained
    if u is None:
        return False
    text = u.where + " " + " ".join(u.correlates_with)
    return text.startswith(CHANNELS[ch]) or (bool(words) and words in text and CHANNELS[ch] in text)


Score = Callable[[Diagnosis, SensorTruth, float], tuple[bool, float]]


def _z(est: float, truth: float, sigma: float) -> float:
    return abs(est - truth) / sigma if sigma > 0 else float("inf")


def score_axis(axis: int, angle: int) -> Score:
    def score(d: Diagnosis, t: SensorTruth, truth: float) -> tuple[bool, float]:
        for f in d.findings:
            if f.effect == "table_axis_error":
                z = _z(f.parameters["angles_rad"][axis][angle], truth, f.sigma["angles_rad"][axis][angle])
                return z < 3.0, z
        return False, float("nan")

    return score


def score_harmonic(
    axis: int, h: int, ch: int, amp_m_s2: Callable[[float], np.ndarray]
) -> Callable[..., tuple[bool, float]]:
    def score(d: Diagnosis, t: SensorTruth, size: float) -> tuple[bool, float]:
        truth = abs(float((t.K @ amp_m_s2(size))[ch]))
        for f in d.findings:
            if (
                f.effect == "angle_harmonic"
                and f.parameters["axis"] == axis + 1
                and f.parameters["harmonic"] == h
            ):
                z = _z(f.parameters["amplitude"][ch], truth, f.sigma["amplitude"][ch])
                return z < 3.0, z
        return _unexplained_on(d, ch), float("nan")

    return score


def score_line(
    freq: float, ch: int, amp_m_s2: Callable[[float], np.ndarray]
) -> Callable[..., tuple[bool, float]]:
    def score(d: Diagnosis, t: SensorTruth, size: float) -> tuple[bool, float]:
        truth = abs(float((t.K @ amp_m_s2(size))[ch]))
        for f in d.findings:
            if (
                f.effect == "periodic_line"
                and abs(f.parameters["frequency_hz"] - freq) < 3 * f.sigma["frequency_hz"] + 1e-9
            ):
                z = _z(f.parameters["amplitude"][ch], truth, f.sigma["amplitude"][ch])
                return z < 3.0, z
        return _unexplained_on(d, ch), float("nan")

    return score


def score_drift(d: Diagnosis, t: SensorTruth, size: float) -> tuple[bool, float]:
    for f in d.findings:
        if f.effect == "clock_drift":
            z = _z(f.parameters["delay_s_per_s"], size, f.sigma["delay_s_per_s"])
            return z < 3.0, z
    return False, float("nan")


def score_hysteresis(axis: int, ch: int) -> Score:
    def score(d: Diagnosis, t: SensorTruth, size: float) -> tuple[bool, float]:
        b = np.zeros(3)
        b[ch] = size * G0
        truth = float((t.K @ b)[ch])
        for f in d.findings:
            if f.effect == "hysteresis":
                z = _z(f.parameters["half_step"][axis][ch], truth, f.sigma["half_step"][axis][ch])
                return z < 3.0, z
        return _unexplained_on(d, ch, "last move"), float("nan")

    return score


def _vec(ch: int, g_units: float) -> np.ndarray:
    v = np.zeros(3)
    v[ch] = g_units * G0
    return v


def _harmonic(label: str, kind: str, mg: float, axis: int, h: int, ch: int) -> FamilyCase:
    def eff(s: float) -> dict[str, dict[str, Any]]:
        amp = _vec(ch, s).tolist()
        return {"angle_harmonic": {"axis": axis, "harmonic": h, "amplitude_m_s2": amp, "phase_rad": 0.4}}

    return FamilyCase(
        f"angle_harmonic: {label}",
        kind,
        mg * 1e-3,
        "g",
        eff,
        ch,
        score_harmonic(axis - 1, h, ch, lambda s: _vec(ch, s)),
    )


def _line(label: str, kind: str, mg: float, freq: float, ch: int) -> FamilyCase:
    def eff(s: float) -> dict[str, dict[str, Any]]:
        return {
            "periodic_line": {"frequency_hz": freq, "amplitude_m_s2": _vec(ch, s).tolist(), "phase_rad": 1.0}
        }

    return FamilyCase(
        f"periodic_line: {label}", kind, mg * 1e-3, "g", eff, ch, score_line(freq, ch, lambda s: _vec(ch, s))
    )


def _hysteresis(axis: int, ug: float) -> FamilyCase:
    def eff(s: float) -> dict[str, dict[str, Any]]:
        return {"hysteresis": {"axis": axis, "bias_m_s2": _vec(1, s).tolist()}}

    return FamilyCase(
        f"hysteresis: axis {axis}, ay, static, {ug:.0f} µg",
        "static",
        ug * 1e-6,
        "g",
        eff,
        1,
        score_hysteresis(axis - 1, 1),
    )


def cases() -> list[FamilyCase]:
    """Every family at its sizes (module docstring)."""
    out: list[FamilyCase] = []
    for deg in (0.02, 0.05, 0.1):
        r = float(np.deg2rad(deg))
        out.append(
            FamilyCase(
                f"table_axis_error: middle axis {deg}° off perpendicular", "static", r, "rad",
                lambda s: {"table_axis_error": {"angles_rad": [[0, 0], [0, s], [0, 0]]}}, 0, score_axis(1, 1),
            )
        )  # fmt: skip
    r = float(np.deg2rad(0.05))
    out.append(
        FamilyCase(
            "table_axis_error: inner axis 0.05° towards the middle one", "static", r, "rad",
            lambda s: {"table_axis_error": {"angles_rad": [[0, 0], [0, 0], [s, 0]]}}, 0, score_axis(2, 0),
        )
    )  # fmt: skip
    for mg in (0.3, 1.0, 3.0):
        out.append(_harmonic(f"outer axis, 2 per turn, ay, rate table, {mg} mg", "rate", mg, 1, 2, 1))
    for mg in (1.0, 2.0):
        out.append(
            _harmonic(f"inner axis, once per turn, ax, oscillation, {mg} mg", "oscillation", mg, 3, 1, 0)
        )
    for mg in (0.3, 1.0, 3.0):
        out.append(_line(f"0.5 Hz on ax, static, {mg} mg", "static", mg, 0.5, 0))
        out.append(_line(f"23.4 Hz on az, oscillation, {mg} mg", "oscillation", mg, 23.4, 2))
    for kind in ("oscillation", "rate"):
        for rho in (2e-5, 1e-4):
            out.append(
                FamilyCase(
                    f"clock_drift: {rho * 1e6:.0f} ppm, {kind}", kind, rho, "s/s",
                    lambda s: {"clock_drift": {"delay_s_per_s": s}}, 0, score_drift,
                    allowed=frozenset({"time_skew", "sensor_lowpass"}),
                )
            )  # fmt: skip
    for axis in (1, 2, 3):
        for ug in (100.0, 300.0):
            out.append(_hysteresis(axis, ug))
    return out


NAV_WHITE_G_RT_HZ = 2e-6
"""White noise of the navigation-grade unit whose window means the encoders' step reaches (g/√Hz)."""
NAV_LSB_V = 3.0 / 2**24
"""A 24-bit converter over 3 V (V)."""
ENCODER_STEP_DEG = 1e-4
"""The simulated bench's encoder step (deg)."""


def navigation_static_recording(seed: int, declared: bool = True) -> Recording:
    """A clean navigation-grade static-12 tumble (2 µg/√Hz white, no wander, 24-bit) on encoders
    that read in steps of 1e-4° with the servo holding each pose within half a step
    (``encoder_hold``); ``declared`` False drops ``table.encoder_resolution_deg`` from the sidecar
    (a recording written before the key)."""
    typ = SensorTruth.typical("V", seed=seed)
    noise = replace(
        typ.noise,
        white_m_s2_rt_hz=NAV_WHITE_G_RT_HZ * G0,
        bias_instability_m_s2=0.0,
        quantization_lsb=NAV_LSB_V,
    )
    truth = typ.with_noise(noise).with_effects({"encoder_hold": {"step_deg": ENCODER_STEP_DEG}})
    run = simulate_static(static12_poses_deg(), 30.0, SensorPhysics(truth, DEFAULT_AXES, seed=seed), 100.0)
    rec = to_recording(run, serial=f"SIM-NAV-{seed}")
    if declared or rec.sidecar.table is None:
        return rec
    table = replace(rec.sidecar.table, encoder_resolution_deg=None)
    return replace(rec, sidecar=replace(rec.sidecar, table=table))
