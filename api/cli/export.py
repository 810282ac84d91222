"""``calbench export RECORDING.csv --format imucal|kalibr|c-header|json [--out FILE]``.

Fits the recording as ``calbench calibrate`` does and writes the correction in the chosen
form (:mod:`bench.export`); ``kalibr`` takes its noise from the Allan curve of the
recording's longest static stretch (:mod:`api.exports`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from api.cli import BadInput
from api.exports import export_text
from api.plots.run_series import allan_series, pick_noise_span
from bench.calibration import calibrate_recording
from bench.export import FORMATS
from bench.recording import read_recording


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench export``."""
    parser.add_argument("recording", type=Path, help="recording CSV (the sidecar JSON is found by stem)")
    parser.add_argument("--format", required=True, choices=FORMATS, help="what to write")
    parser.add_argument("--out", type=Path, default=None, help="file to write (default: standard output)")


def run(args: argparse.Namespace) -> int:
    """Fit one recording and write its export."""
    path: Path = args.recording
    if not path.is_file():
        raise BadInput(f"{path}: no such recording file")
    try:
        rec = read_recording(path)
    except OSError as exc:
        raise BadInput(str(exc)) from exc
    cal = calibrate_recording(rec)
    allan = None
    if args.format == "kalibr":
        static = [(w.start_s, w.end_s) for w in cal.windows]
        s, e, source = pick_noise_span(rec, [], static)
        allan = allan_series(rec, s, e, source)
    text = export_text(args.format, cal.fitted_model(), allan, f"from {path.name}")
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.write_text(text, encoding="utf-8")
    return 0
