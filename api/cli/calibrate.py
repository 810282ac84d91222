"""``calbench calibrate RECORDING.csv [--json]``: fit bias and scale/misalignment.

Human output: the coefficients with their one-sigma uncertainties, the per-window
residuals and |g| errors, and the |g| check summary. ``--json``: the object of
``docs/cli-contract.md``. Bad input: exit 2 with one line (raised as ValueError).
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from api.cli import BadInput, decimal_arg

if TYPE_CHECKING:
    from bench.calibration import CalibrationResult


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench calibrate``."""
    parser.add_argument("recording", type=Path, help="recording CSV (the sidecar JSON is found by stem)")
    parser.add_argument("--json", action="store_true", help="print the machine-readable result")
    parser.add_argument(
        "--nominal-scale",
        type=decimal_arg,
        default=None,
        help="nominal sensitivity (channel unit per m/s²) for the 'before' |g| check of V or count channels",
    )
    parser.add_argument(
        "--nominal-bias",
        type=decimal_arg,
        nargs=3,
        default=None,
        metavar=("BX", "BY", "BZ"),
        help="nominal zero-g output (channel unit) used with --nominal-scale; required with it for V or "
        "count channels (0 is implied for g and m/s2)",
    )
    parser.add_argument(
        "--terms",
        default=None,
        metavar="TERM,...",
        help="moving-table recordings: fit these terms beyond bias and K (e.g. the unit model's: "
        "lever_arm, table_tilt, ...; an unknown term is refused with the list; 'none' for the "
        "first-order model) instead of the terms the recording's evidence supports (the default)",
    )


def run(args: argparse.Namespace) -> int:
    """Calibrate one recording and print the result."""
    import numpy as np  # the numerical stack is imported by the command that needs it

    from bench.calibration import NATURAL_ZERO_UNITS, is_moving
    from bench.calibration.analysis import analyse
    from bench.recording import read_recording

    path: Path = args.recording
    if not path.is_file():
        raise BadInput(f"{path}: no such recording file")
    if args.nominal_bias is not None and args.nominal_scale is None:
        raise BadInput("--nominal-bias needs --nominal-scale")
    try:
        rec = read_recording(path)
    except OSError as exc:  # a missing or unreadable sidecar is bad input, one line
        raise BadInput(str(exc)) from exc
    unit = rec.sidecar.channel_unit
    if args.nominal_scale is not None and args.nominal_bias is None and unit not in NATURAL_ZERO_UNITS:
        raise BadInput(
            f"{path}: --nominal-scale for a {unit} channel needs --nominal-bias BX BY BZ "
            f"(the nominal zero-g output; a {unit} output is not 0 at zero g)"
        )
    bias0 = None if args.nominal_bias is None else np.array(args.nominal_bias, dtype=float)
    terms = None if args.terms is None else _terms(path, args.terms)
    if terms is not None and not is_moving(rec):
        raise BadInput(f"{path}: --terms applies to moving-table recordings; this one is static")
    result = analyse(rec, nominal_scale=args.nominal_scale, nominal_bias=bias0, terms=terms).fit
    warn_implausible(result)
    if args.json:
        print(json.dumps(result.to_contract()))
    else:
        print(format_human(result))
    return 0


def _terms(path: Path, text: str) -> tuple[str, ...]:
    """``--terms`` as a tuple of dynamic-model terms ('none': the first-order model)."""
    from bench.calibration.kind import CANDIDATE_TERMS

    if text.strip().lower() == "none":
        return ()
    terms = tuple(t.strip() for t in text.split(",") if t.strip())
    bad = [t for t in terms if t not in CANDIDATE_TERMS]
    if bad or not terms:
        raise BadInput(
            f"{path}: --terms {text!r}: expected 'none' or a comma-separated list of "
            + ", ".join(CANDIDATE_TERMS)
        )
    return terms


def warn_implausible(r: CalibrationResult) -> None:
    """Each of the result's warnings (the plausibility checks of ``bench.recording.plausibility``
    among them: spikes, clipping, encoder resolution and lag, the fitted frame and gains) also on
    stderr, one line each after the result."""
    for text in r.warnings:
        warnings.warn(text, UserWarning, stacklevel=2)


def _pm(value: float, sigma: float) -> str:
    return f"{value: .8g} ± {sigma:.2g}"


def format_human(r: CalibrationResult) -> str:
    """Readable report: coefficients, per-window table, |g| check."""
    from bench.calibration.kind import FitKind

    u = r.channel_unit
    lines = [
        f"unit {r.unit_serial}   procedure {r.procedure}   fit: {r.kind.text}",
        f"source {r.source}" if r.source else "",
        "",
        f"bias ({u}), one sigma:",
    ]
    lines += [f"  {ax}  {_pm(b, s)}" for ax, b, s in zip("xyz", r.bias, r.bias_sigma, strict=True)]
    lines += ["", f"scale matrix K ({u} per m/s²), raw = bias + K·f, one sigma:"]
    for i, ax in enumerate("xyz"):
        lines.append(f"  {ax}  " + "   ".join(_pm(r.K[i, j], r.K_sigma[i, j]) for j in range(3)))
    lines += r.model_lines()  # terms beyond bias and K, and how they were chosen (moving table)
    scalar = r.kind is FitKind.ORIENTATION_FREE
    lines += [
        "",
        "correction: f = K⁻¹ (raw − bias)   (m/s²)",
        f"noise model: {r.noise_model}",
        # a dynamic fit scales its residuals by their own fitted sigma: its chi2 is no test of fit
        f"residual rms {r.residual_rms:.3g} {u}"
        + ("" if r.kind is FitKind.MOVING else f"   chi2/dof (within-window noise) {r.chi2:.4g}/{r.dof}")
        + ("   ZERO REDUNDANCY" if r.zero_redundancy else ""),
        "",
        f"{'window':<10}{'t (s)':>17}{'n':>7}  {'residual x,y,z (' + u + ')':<36}"
        f"{'|g| z-score' if scalar else 'z-scores x,y,z':<20}{'|g| err after':>14}{'before':>11}",
    ]
    for w in r.windows:
        res = " ".join(f"{v: .2e}" for v in w.residual)
        # the scalar fit has one residual per window, (|f̂| − g)/σ, stored on all three axes
        zs = w.normalized_residual[:1] if scalar else w.normalized_residual
        z = " ".join(f"{v: .1f}" for v in zs)
        before = "" if w.g_error_before_m_s2 is None else f"{w.g_error_before_m_s2: .3e}"
        lines.append(
            f"{w.label:<10}{w.start_s:>8.2f}-{w.end_s:<8.2f}{w.n_samples:>7}  {res:<36}{z:<20}"
            f"{w.g_error_after_m_s2:>14.3e}{before:>11}"
        )
    lines += ["", f"|g| check against g_local = {r.g_local_m_s2} m/s² (mean error, std over windows):"]
    if r.g_before is not None:
        lines.append(f"  before  {r.g_before.mean_error_m_s2: .3e}  {r.g_before.std_m_s2:.3e} m/s²")
    lines.append(f"  after   {r.g_after.mean_error_m_s2: .3e}  {r.g_after.std_m_s2:.3e} m/s²")
    if r.unused_windows:
        lines += ["", "declared windows not used:"]
        lines += [
            f"  {w.label:<10}{w.start_s:>8.2f}-{w.end_s:<8.2f}{w.n_samples:>7}  {w.reason}"
            for w in r.unused_windows
        ]
    if r.warnings:
        lines += [""] + [f"WARNING: {text}" for text in r.warnings]
    return "\n".join(line for line in lines if line is not None)
