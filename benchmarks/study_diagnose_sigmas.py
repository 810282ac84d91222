"""Are the sigmas ``calbench diagnose`` reports honest? A z-score study on simulated static-12 runs.

``python -m benchmarks.study_diagnose_sigmas [quick|full|N] [case ...]``: for each case
below, N recordings (seeds 200…; quick 10, full 40) with the effect concealed at about 10x
its detection limit, so that it is found; for every recording where it is found,
z = (estimate − truth) / sigma of the reported coefficient. Prints, as a markdown table per
case: recordings where it was found, mean z, RMS z, the share with |z| > 3, the median
|estimate|/sigma (how far above zero the coefficient lies), and the median slow-noise
sigma of the final model. With honest sigmas z has mean 0 and RMS 1 (RMS of N unit normals:
1 ± 1/sqrt(2N), ±0.11 at N = 40) and |z| > 3 in 0.3 % of recordings.

Every recording carries what real static data carry: the typical triad's 40 µg
Gauss-Markov bias wander (200 s correlation time) and 250 µg/√Hz white noise, the lab
default warm-up temperature (or a ±1.5 °C cycle where a case needs temperature apart from
time), and small pose errors, 1e-5 rad rms per window and angle (a fifth of their detection
limit, so the diagnosis does not claim them: they are noise it must carry).

The truth is in the reported unit by construction, worked out here and not read from the
diagnosis: a library term is added to the raw channel as ``coefficient · x`` with x the
term in the contract's units (g = 9.80665 m/s² from the encoder angles, °C − 25, s since the
first sample; ``benchmarks.library_cases``), so the reported coefficient (channel unit per
unit of the term) is ``coefficient`` itself; a catalogue effect is simulated from its
contract parameter (``tests.support.diagnose_cases``), which is what the finding reports.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.calibration.diagnose import diagnose_recording
from bench.diagnosis import Diagnosis
from bench.recording import Recording
from benchmarks.library_cases import CASES as LIBRARY
from benchmarks.library_cases import conceal
from tests.support.diagnose_cases import CASES as CATALOGUE
from tests.support.diagnose_cases import N_WINDOWS, static_recording

POSE_RMS_RAD = 1.0e-5
"""Pose error concealed in every recording (rad rms per window and angle): 0.2x its limit."""
SIZES = {"quick": 10, "full": 40}
FIRST_SEED = 200


def pose_angles(seed: int) -> dict[str, Any]:
    """The small pose error of recording ``seed`` ((12, 2) angles, rad)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x5160]))
    return {"angles_rad": (POSE_RMS_RAD * rng.standard_normal((N_WINDOWS, 2))).tolist()}


@dataclass(frozen=True)
class SigmaCase:
    """One concealed effect: how to simulate it and where its estimate and sigma are reported.

    :param name: the case; :param truth: the concealed value in the reported unit.
    :param recording: seed -> the simulated recording.
    :param estimate: diagnosis -> (estimate, sigma), or ``None`` when not found.
    """

    name: str
    truth: float
    unit: str
    recording: Callable[[int], Recording]
    estimate: Callable[[Diagnosis], tuple[float, float] | None]


def library_case(name: str, size: float) -> SigmaCase:
    """A concealed library term at ``size`` times its scenario's coefficient."""
    lib = LIBRARY[name]
    ch = ("ax", "ay", "az")[lib.channel]
    coefficient = size * lib.coefficient

    def rec(seed: int) -> Recording:
        base = static_recording({"pose_error": pose_angles(seed)}, seed, temperature=lib.temperature)
        return conceal(base, lib.channel, lib.quantity(base), coefficient)

    def est(d: Diagnosis) -> tuple[float, float] | None:
        hit = next((x for x in d.discovered if x.channel == ch and x.term == lib.term), None)
        return None if hit is None else (hit.coefficient, hit.sigma)

    return SigmaCase(f"{name}: {lib.term} on {ch}", coefficient, "V per unit", rec, est)


def catalogue_case(effect: str, times_limit: float) -> SigmaCase:
    """A concealed catalogue effect at ``times_limit`` times its detection limit."""
    case = CATALOGUE[effect]
    size = times_limit * case.limit
    truth = float(np.asarray(case.build(size, 0)[case.parameter], dtype=float)[case.index])

    def rec(seed: int) -> Recording:
        effects = {effect: case.build(size, seed), "pose_error": pose_angles(seed)}
        return static_recording(effects, seed, temperature=case.temperature)

    def est(d: Diagnosis) -> tuple[float, float] | None:
        f = next((x for x in d.findings if x.effect == effect), None)
        if f is None or case.parameter not in f.sigma:
            return None
        e = np.asarray(f.parameters[case.parameter], dtype=float)[case.index]
        s = np.asarray(f.sigma[case.parameter], dtype=float)[case.index]
        return float(e), float(s)

    label = f"{effect}: {case.parameter}{list(case.index)}"
    return SigmaCase(label, truth, case.unit, rec, est)


def cases() -> list[SigmaCase]:
    """The study's cases, each at about 10x its detection limit (docs/diagnose.md)."""
    return [
        library_case("scale_temperature", 4.0),
        library_case("fixture_temperature", 4.0),
        library_case("mount_creep", 2.0),
        catalogue_case("nonlinearity_quadratic", 10.0),
        catalogue_case("cross_coupling", 10.0),
        catalogue_case("bias_drift", 10.0),
    ]


@dataclass(frozen=True)
class ZStats:
    """z = (estimate − truth)/sigma over the recordings where the effect was found."""

    n: int
    found: int
    z: tuple[float, ...]
    snr: tuple[float, ...]
    slow_sigma: tuple[float, ...]

    @property
    def mean(self) -> float:
        """Mean z (0 for unbiased estimates)."""
        return float(np.mean(self.z)) if self.z else float("nan")

    @property
    def rms(self) -> float:
        """RMS z (1 for honest sigmas)."""
        return float(np.sqrt(np.mean(np.square(self.z)))) if self.z else float("nan")

    @property
    def beyond3(self) -> float:
        """Share of the found recordings with |z| > 3 (0.27 % for honest Gaussian sigmas)."""
        return float(np.mean(np.abs(self.z) > 3.0)) if self.z else float("nan")


def slow_sigma(d: Diagnosis) -> float:
    """The final model's slow-noise sigma, largest channel (channel units), from its noise text."""
    text = d.noise_text.split("sigma = [", 1)[1].split("]", 1)[0]
    return max(float(v) for v in text.split(","))


def z_stats(case: SigmaCase, seeds: range) -> ZStats:
    """Simulate, diagnose and score ``case`` on every seed."""
    zs, snr, tau = [], [], []
    for seed in seeds:
        d = diagnose_recording(case.recording(seed))
        hit = case.estimate(d)
        if hit is None:
            continue
        est, sig = hit
        zs.append((est - case.truth) / sig)
        snr.append(abs(est) / sig)
        tau.append(slow_sigma(d))
    return ZStats(len(seeds), len(zs), tuple(zs), tuple(snr), tuple(tau))


def main(argv: list[str] | None = None) -> None:
    """Print the study (module docstring)."""
    args = sys.argv[1:] if argv is None else argv
    size = args[0] if args else "quick"
    n = SIZES[size] if size in SIZES else int(size)
    wanted = args[1:]
    t0 = time.perf_counter()
    print(f"{n} recordings per case (seeds {FIRST_SEED}–{FIRST_SEED + n - 1})")
    print(
        "| case | truth | found | mean z | RMS z | abs z > 3 | median abs estimate/sigma "
        "| median slow sigma (V) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for case in cases():
        if wanted and not any(w in case.name for w in wanted):
            continue
        s = z_stats(case, range(FIRST_SEED, FIRST_SEED + n))
        print(
            f"| {case.name} | {case.truth:.3g} {case.unit} | {s.found}/{s.n} | {s.mean:+.2f} | {s.rms:.2f} | "
            f"{s.beyond3:.0%} | {np.median(s.snr):.0f} | {np.median(s.slow_sigma):.1e} |",
            flush=True,
        )
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
