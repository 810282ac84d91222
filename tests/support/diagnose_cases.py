"""Concealed-effect scenarios for ``calbench diagnose``: one simulated static-12 recording per
(effect, size, seed), the parameter checked, and the scoring of a diagnosis against the truth.

Shared by ``tests/bench/test_concealed_effects.py`` and ``benchmarks/study_diagnose_detection.py``
(the detection table of docs/diagnose.md). Recording: a typical ADXL-like triad
(``SensorTruth.typical``, V, 100 Hz, 250 µg/√Hz white noise, 40 µg Gauss-Markov bias wander
with a 200 s correlation time) on the 12-pose tumble, 30 s windows, 2 s after each stop.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration.diagnose import diagnose_recording
from bench.diagnosis import Diagnosis
from bench.diagnosis.thresholds import Thresholds
from bench.estimation.spectral_lines import FALSE_ALARM as LINE_FALSE_ALARM
from bench.recording import Recording
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth, TemperatureModel

N_WINDOWS = 12
CYCLING_TEMPERATURE = TemperatureModel(warmup_rise_c=0.0, cycle_amplitude_c=1.5, cycle_period_s=150.0)
"""A sensor whose temperature cycles (±1.5 °C, 150 s) with no warm-up, so temperature and
time are not collinear over the ~450 s of windows (a thermal chamber, not the lab default)."""


def clean_finding_rate(th: Thresholds) -> float:
    """Nominal share of clean static recordings with a finding or a discovered term: the union
    (Bonferroni) bound of the levels of the stages that can claim on one, the first selection
    step's ``false_alarm`` (the library's ``library_share`` of it included; a clean selection
    stops there), the settling test's ``settling_share``·``false_alarm`` and the line finder's
    ``spectral_lines.FALSE_ALARM``: 0.01 + 0.001 + 0.001 = 0.012 at the defaults."""
    return th.false_alarm * (1.0 + th.settling_share) + LINE_FALSE_ALARM


def static_recording(
    effects: dict[str, dict[str, Any]],
    seed: int,
    dwell_s: float = 30.0,
    temperature: TemperatureModel | None = None,
) -> Recording:
    """A typical ADXL-like triad (V, 100 Hz, bias wander included) on the 12-pose tumble."""
    truth = SensorTruth.typical("V", seed=seed).with_effects(effects)
    physics = SensorPhysics(truth, DEFAULT_AXES, seed=seed, temperature=temperature)
    run = simulate_static(static12_poses_deg(), dwell_s, physics, 100.0)
    return to_recording(run, serial=f"SIM-{seed}")


@dataclass(frozen=True)
class Case:
    """One catalogue effect concealed at a given size.

    :param effect: catalogue id; :param limit: measured detection limit (``unit``).
    :param unit: unit of the size; :param build: (size, seed) -> the effect's truth parameters.
    :param parameter: contract parameter checked; :param index: its element.
    :param temperature: temperature course of the recording (``None``: the lab default).
    """

    effect: str
    limit: float
    unit: str
    build: Callable[[float, int], dict[str, Any]]
    parameter: str
    index: tuple[int, ...] = ()
    temperature: TemperatureModel | None = None

    def recording(self, size: float, seed: int) -> Recording:
        """The simulated recording with the effect at ``size``."""
        return static_recording({self.effect: self.build(size, seed)}, seed, temperature=self.temperature)


def _pose_angles(size: float, seed: int) -> dict[str, Any]:
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x905E]))
    return {"angles_rad": (size * rng.standard_normal((N_WINDOWS, 2))).tolist()}


CASES: dict[str, Case] = {
    c.effect: c
    for c in (
        Case(
            "nonlinearity_quadratic",
            1.8e-4,
            "1/g",
            lambda s, _: {"k2_per_g": [0.0, 0.0, s]},
            "k2_per_g",
            (2,),
        ),
        Case("scale_asymmetry", 4.1e-4, "1", lambda s, _: {"delta": [s, 0.0, 0.0]}, "delta", (0,)),
        Case(
            "cross_coupling",
            3.6e-4,
            "1/g",
            lambda s, _: {"c_per_g": [[0.0, 0.0, s], [0.0] * 3, [0.0] * 3]},
            "c_per_g",
            (0, 2),
        ),
        Case(
            "temperature_bias",
            7.4e-4,
            "m/s²/°C",
            lambda s, _: {"tc_m_s2_per_c": [0.0, s, 0.0]},
            "tc_m_s2_per_c",
            (1,),
            CYCLING_TEMPERATURE,
        ),
        Case(
            "bias_drift",
            7.2e-6,
            "m/s²/s",
            lambda s, _: {"drift_m_s2_per_s": [s, 0.0, 0.0]},
            "drift_m_s2_per_s",
            (0,),
            CYCLING_TEMPERATURE,
        ),
        Case("table_tilt", 8.0e-5, "rad", lambda s, _: {"tilt_rad": [s, 0.0]}, "tilt_rad", (0,)),
        Case("pose_error", 5.0e-5, "rad rms", _pose_angles, "angles_rad"),
        Case("encoder_offset", 6.0e-3, "deg", lambda s, _: {"offset_deg": [0.0, s, 0.0]}, "offset_deg", (1,)),
        Case("settling", 50.0, "s", lambda s, _: {"duration_s": s}, "duration_s"),
    )
}
"""Every effect a static recording can show, with its measured limit (docs/diagnose.md)."""


@dataclass(frozen=True)
class Score:
    """How one diagnosis did: found, parameter error in sigmas, the other findings."""

    found: bool
    z: float
    others: tuple[str, ...]


def score(case: Case, d: Diagnosis, truth: dict[str, Any]) -> Score:
    """Score a diagnosis against the concealed truth.

    z is (estimate − truth)/sigma of the checked element; for ``pose_error`` the RMS of that
    ratio over every window's two angles (their predictions and posterior sigmas).
    """
    by = {f.effect: f for f in d.findings}
    others = tuple(e for e in by if e != case.effect)
    f = by.get(case.effect)
    if f is None or case.parameter not in f.parameters or case.parameter not in f.sigma:
        return Score(False, float("nan"), others)
    est = np.asarray(f.parameters[case.parameter], dtype=float)
    sig = np.asarray(f.sigma[case.parameter], dtype=float)
    tru = np.asarray(truth[case.parameter], dtype=float)
    if case.index:
        est, sig, tru = est[case.index], sig[case.index], tru[case.index]
    z = (est - tru) / sig
    return Score(True, float(np.sqrt(np.mean(z**2))) if z.ndim else float(z), others)


def run_case(case: Case, size: float, seed: int) -> Score:
    """Simulate, diagnose and score one recording."""
    return score(case, diagnose_recording(case.recording(size, seed)), case.build(size, seed))
