"""``calbench diagnose RECORDING.csv [--json] [--report OUT.html]``: find the physics the model left out.

Human output: the mismatch of the first-order model, each finding with its parameters
and the BIC change, each term found beyond the catalogue (DISCOVERED), the final fit and,
when it still fails the recording's noise, where (UNEXPLAINED), and the effects this
recording cannot show.
``--json``: the object of ``docs/cli-contract.md``. ``--report``: a self-contained HTML
page with residual plots. Bad input: exit 2 with one line (raised as ValueError).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

from api.cli import BadInput

if TYPE_CHECKING:
    from bench.diagnosis.result import Diagnosis


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench diagnose``."""
    parser.add_argument("recording", type=Path, help="recording CSV (the sidecar JSON is found by stem)")
    parser.add_argument("--json", action="store_true", help="print the machine-readable result")
    parser.add_argument("--report", type=Path, default=None, help="write an HTML report with plots here")


def run(args: argparse.Namespace) -> int:
    """Diagnose one recording and print the result."""
    from bench.calibration.diagnose import diagnose_recording  # numerical stack: only when it runs
    from bench.recording import read_recording

    path: Path = args.recording
    if not path.is_file():
        raise BadInput(f"{path}: no such recording file")
    if args.report is not None and not args.report.parent.is_dir():
        raise BadInput(f"{args.report}: directory {args.report.parent} does not exist")
    rec = read_recording(path)
    result = diagnose_recording(rec)
    if args.report is not None:
        from api.reports.diagnose_html import render

        args.report.write_text(render(result), encoding="utf-8")
    if args.json:
        print(json.dumps(result.to_contract()))
    else:
        print(format_human(result))
    return 0


def format_human(d: Diagnosis) -> str:
    """Readable report of a diagnosis."""
    u = d.channel_unit
    b = d.baseline
    lines = [
        f"unit {d.unit}   {d.source}",
        f"first-order model: residual rms {b.residual_rms:.3g} {u}, "
        f"chi2/dof {b.chi2_dof:.3g}, BIC {b.bic:.1f}",
        "mismatch (chi2/dof per channel): "
        + ", ".join(f"{c} {r:.2f}" for c, r in zip(("ax", "ay", "az"), d.channel_ratio, strict=True)),
        f"where: {d.where}",
        f"correlates with: {', '.join(d.correlates_with()) or 'nothing significant'}",
        "",
    ]
    if not d.findings and not d.discovered:
        lines.append(
            "findings: none - the first-order model explains the recording to its noise"
            if d.fits
            else "findings: none from the catalogue or the library (see UNEXPLAINED below)"
        )
    for f in d.findings:
        lines += [
            f"FOUND {f.effect}: {f.summary}",
            f"    why: {f.explanation}",
            f"    delta BIC {f.delta_bic:.1f}, likelihood ratio {f.lr:.1f}, "
            f"residual rms after {f.residual_rms_after:.3g} {u}",
        ]
    for x in d.discovered:
        lines += [
            f"DISCOVERED {x.term} on {x.channel}: {x.coefficient:.3g} ± {x.sigma:.2g} {x.unit}",
            f"    why: {x.physics}",
            f"    delta BIC {x.delta_bic:.1f}, residual rms after {x.residual_rms_after:.3g} {u}",
        ]
    fin = d.final
    lines += [
        "",
        f"final model {' + '.join(fin.terms)}: residual rms {fin.residual_rms:.3g} {u}, "
        f"chi2/dof {fin.chi2_dof:.3g}, BIC {fin.bic:.1f}",
    ]
    if d.unexplained is not None:
        ux = d.unexplained
        lines += [
            "UNEXPLAINED: the final model still fails the recording's own noise "
            f"({ux.test}): {ux.where}; correlates with "
            f"{', '.join(ux.correlates_with) or 'nothing significant'}",
        ]
    lines += [
        "",
        "not observable in this recording:",
    ]
    lines += [f"  {k}: {v}" for k, v in d.unobservable.items()]
    lines += ["", "notes:"] + [f"  {n}" for n in d.notes]
    return "\n".join(lines)
