"""``calbench allan REC.csv [--json] [--plot out.png] [--window-s START END]``.

Allan deviation of a static stretch of a recording, the noise terms fitted to it and the
dwell it recommends. The stretch is ``--window-s``, else the longest sidecar segment the
calibration holds still (a pose, not a turn between poses), else the longest static window
found in the data, else the whole file (``--whole`` forces it). Channels in ``g`` are
converted to m/s²; ``V`` and ``count`` stay in their own unit.
Periodic lines (``bench.estimation.spectral_lines``) are found first and reported with
channel, frequency and amplitude; they are subtracted before the Allan deviation, so a 0.5 Hz
vibration is not read as white noise nor a 23.4 Hz one as quantisation noise. A warning
names each channel whose Allan curve the noise model does not describe (χ² above its 95 %
point: its sigmas then carry the model allowance).
Human output: a τ / σ_A table with intervals, the lines, the noise terms, the dwell and the
warnings. ``--json``: one object (fields in ``docs/cli-contract.md`` style). Bad input: exit
2, one line.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from api.cli import BadInput, decimal_arg
from bench.calibration.noise_stretch import noise_channels, select_noise_stretch
from bench.estimation.allan import AllanResult, overlapping_allan
from bench.estimation.dwell import DwellRecommendation, recommend_dwell_s
from bench.estimation.noise_terms import NoiseTerms, fit_noise_model, slope_method
from bench.estimation.spectral_lines import SpectralLine, find_lines, remove_lines
from bench.recording import Recording, read_recording

CHANNELS = ("ax", "ay", "az")
NOISE_MODEL = (
    "sigma^2(tau) = 3 Q^2/tau^2 + N^2/tau + (0.664 B)^2 + K^2 tau/3 + R^2 tau^2/2"
    " + 2 s_gm^2 T_c/tau [1 - T_c/(2 tau) (3 - 4 exp(-tau/T_c) + exp(-2 tau/T_c))] (IEEE 952 C)"
)
MAX_GAP_FACTOR = 1.5
"""A step between time stamps longer than this many sample periods is a gap."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench allan``."""
    parser.add_argument("recording", type=Path, help="recording CSV (the sidecar JSON is found by stem)")
    parser.add_argument("--json", action="store_true", help="print the machine-readable result")
    parser.add_argument("--plot", type=Path, default=None, metavar="OUT.png", help="write a log-log plot")
    parser.add_argument(
        "--window-s",
        type=decimal_arg,
        nargs=2,
        default=None,
        metavar=("START", "END"),
        help="analyse START ≤ t ≤ END (s)",
    )
    parser.add_argument("--whole", action="store_true", help="analyse the whole file")
    parser.add_argument("--taus", choices=("octave", "decade", "all"), default="octave", help="τ grid")


def _check_even_spacing(rec: Recording, sl: slice) -> None:
    t = rec.t_s[sl]
    period = 1.0 / rec.sidecar.sample_rate_hz
    steps = np.diff(t)
    bad = np.flatnonzero(steps > MAX_GAP_FACTOR * period)
    if bad.size:
        i = int(bad[0])
        raise BadInput(
            f"{rec.source}: gap of {steps[i]:.6g} s after t = {t[i]:.6g} s (sample period {period:.6g} s); "
            "the Allan deviation needs evenly spaced samples: choose --window-s on one side of it"
        )


def _clean(x: Any) -> Any:
    """NaN/inf to None, numpy to Python, recursively (JSON has no NaN)."""
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, float | np.floating):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def noise_units(u: str) -> dict[str, str]:
    """Units of the noise terms for data in unit u."""
    return {
        "quantization_q": f"{u}*s",
        "white_n": f"{u}*sqrt(s)",
        "bias_instability_b": u,
        "rate_random_walk_k": f"{u}/sqrt(s)",
        "rate_ramp_r": f"{u}/s",
        "gauss_markov_level": u,
        "gauss_markov_tc_s": "s",
    }


def to_json(
    rec: Recording,
    unit: str,
    source: str,
    sl: slice,
    r: AllanResult,
    fits: tuple[NoiseTerms, ...],
    slopes: tuple[NoiseTerms, ...],
    dwell: DwellRecommendation,
    lines: tuple[SpectralLine, ...] = (),
    warnings: tuple[str, ...] = (),
) -> dict[str, Any]:
    """The ``--json`` object."""
    by_ch = dict(zip(CHANNELS, range(3), strict=True))
    doc: dict[str, Any] = _clean(  # a dict stays a dict through _clean
        {
            "unit": rec.sidecar.unit_serial,
            "channel_unit": rec.sidecar.channel_unit,
            "adev_unit": unit,
            "sample_rate_hz": rec.sidecar.sample_rate_hz,
            "window": {
                "source": source,
                "start_s": float(rec.t_s[sl][0]),
                "end_s": float(rec.t_s[sl][-1]),
                "n_samples": r.n_samples,
            },
            "ci_level": r.ci_level,
            "taus_s": r.taus_s,
            "adev": {n: r.adev[:, c] for n, c in by_ch.items()},
            "adev_lo": {n: r.adev_lo[:, c] for n, c in by_ch.items()},
            "adev_hi": {n: r.adev_hi[:, c] for n, c in by_ch.items()},
            "edf": {n: r.edf[:, c] for n, c in by_ch.items()},
            "lines": [
                {
                    "channel": CHANNELS[ln.channel],
                    "frequency_hz": ln.frequency_hz,
                    "amplitude": ln.amplitude,
                    "ratio_to_median": ln.ratio_to_median,
                }
                for ln in lines
            ],
            "lines_removed": bool(lines),
            "warnings": list(warnings),
            "noise_terms": {
                "model": NOISE_MODEL,
                "units": noise_units(unit),
                "channels": {n: fits[c].as_dict() for n, c in by_ch.items()},
                "slope_method": {n: slopes[c].as_dict() for n, c in by_ch.items()},
            },
            "dwell": {
                "dwell_s": dwell.dwell_s,
                "floor_reached": dwell.floor_reached,
                "reason": dwell.reason,
                "per_channel": {
                    CHANNELS[p.channel]: {
                        "dwell_s": p.dwell_s,
                        "adev_at_dwell": p.adev_at_dwell,
                        "floor_reached": p.floor_reached,
                        "white_departure_s": p.white_departure_s,
                        "reason": p.reason,
                    }
                    for p in dwell.per_channel
                },
            },
        }
    )
    return doc


def _pm(value: float, sigma: float) -> str:
    if not math.isfinite(value):
        return "—"
    if value == 0.0:
        return f"0 (< {sigma:.2g})"
    return f"{value:.4g} ± {sigma:.2g}"


def format_human(
    rec: Recording,
    unit: str,
    source: str,
    sl: slice,
    r: AllanResult,
    fits: tuple[NoiseTerms, ...],
    dwell: DwellRecommendation,
    found: tuple[SpectralLine, ...] = (),
    warnings: tuple[str, ...] = (),
) -> str:
    """Readable report: τ table with intervals, lines, noise terms, dwell, warnings."""
    t = rec.t_s[sl]
    lines = [
        f"{rec.sidecar.unit_serial}: Allan deviation of {r.n_samples} samples at {r.sample_rate_hz:g} Hz, "
        f"t = {t[0]:g} to {t[-1]:g} s ({source}); unit {unit}; intervals {100 * r.ci_level:.0f} % (χ², edf)",
        "",
        f"{'tau (s)':>10}" + "".join(f"  {n + ' [lo, hi]':<34}" for n in CHANNELS),
    ]
    for k, tau in enumerate(r.taus_s):
        row = f"{tau:>10.4g}"
        for c in range(3):
            row += f"  {r.adev[k, c]:<10.4g} [{r.adev_lo[k, c]:.3g}, {r.adev_hi[k, c]:.3g}]".ljust(36)
        lines.append(row)
    units = noise_units(unit)
    if found:
        lines += ["", f"periodic lines (subtracted before the Allan deviation; amplitude in {unit}):"]
        lines += [
            f"  {CHANNELS[ln.channel]}  {ln.frequency_hz:.6g} Hz  amplitude {ln.amplitude:.3g}"
            f"  ({ln.ratio_to_median:.0f}× the local median spectrum)"
            for ln in found
        ]
    lines += ["", f"noise terms (fit of {NOISE_MODEL}):"]
    names = {
        "white_n": "N white / velocity random walk",
        "bias_instability_b": "B bias instability",
        "rate_random_walk_k": "K rate random walk",
        "quantization_q": "Q quantisation",
        "rate_ramp_r": "R rate ramp",
        "gauss_markov_level": "s_gm Gauss-Markov bias",
        "gauss_markov_tc_s": "T_c its correlation time",
    }
    for key, label in names.items():
        vals = "".join(f"{_pm(getattr(f, key), getattr(f, key + '_sigma')):>24}" for f in fits)
        lines.append(f"  {label:<32}{vals}   {units[key]}")
    lines.append(f"  {'chi2/dof':<32}" + "".join(f"{f.chi2_dof:>24.3g}" for f in fits))
    lines += ["", dwell.reason, *[f"  {p.reason}" for p in dwell.per_channel]]
    if not dwell.floor_reached:
        lines.append("the noise floor was not reached: record a longer static stretch to find it")
    if warnings:
        lines += [""] + [f"WARNING: {text}" for text in warnings]
    return "\n".join(lines)


def fit_warnings(fits: tuple[NoiseTerms, ...]) -> tuple[str, ...]:
    """One sentence per channel whose Allan curve the noise model does not describe."""
    return tuple(
        f"{CHANNELS[c]}: the noise model does not describe the Allan curve (chi2/dof {f.chi2_dof:.3g} "
        f"above its 95 % point); the noise-term sigmas include a {100 * f.model_floor_rel:.2g} % "
        f"allowance on every point, correlated over {f.model_floor_corr_octaves:.3g} octaves of tau, "
        "and the model's own misfit"
        for c, f in enumerate(fits)
        if math.isfinite(f.model_floor_rel) and f.model_floor_rel > 0.0
    )


def run(args: argparse.Namespace) -> int:
    """Analyse one recording and print the result."""
    path: Path = args.recording
    if not path.is_file():
        raise BadInput(f"{path}: no such recording file")
    rec = read_recording(path)
    stretch_at = select_noise_stretch(rec, args.window_s, whole=args.whole)
    sl, source = stretch_at.samples, stretch_at.source
    _check_even_spacing(rec, sl)
    channels = noise_channels(rec)
    unit, data = channels.unit, channels.data
    n = sl.stop - sl.start
    if n < 16:
        raise BadInput(
            f"{path}: the analysed stretch ({source}) has {n} samples; the noise fit needs at least 16"
        )
    fs = rec.sidecar.sample_rate_hz
    stretch = data[sl]
    lines = find_lines(stretch, fs) if n >= 64 else ()
    if lines:
        stretch, lines = remove_lines(stretch, fs, lines)
    r = overlapping_allan(stretch, fs, args.taus)
    if r.taus_s.size < 6:
        raise BadInput(f"{path}: {n} samples give only {r.taus_s.size} τ values; the noise fit needs 6")
    fits = fit_noise_model(r)
    slopes = slope_method(r)
    warnings = fit_warnings(fits)
    dwell = recommend_dwell_s(r, fits, CHANNELS)
    if args.plot is not None:
        from api.plots.allan import allan_figure, save_allan_png

        title = f"{rec.sidecar.unit_serial}: {path.name}, {source}"
        save_allan_png(allan_figure(r, CHANNELS, unit, fits, dwell, title), args.plot)
    if args.json:
        print(json.dumps(to_json(rec, unit, source, sl, r, fits, slopes, dwell, lines, warnings)))
    else:
        print(format_human(rec, unit, source, sl, r, fits, dwell, lines, warnings))
    return 0
