"""``calbench convert {imu_tk,imucal} SOURCE... -o OUT.csv``: another tool's data set as calbench-recording/1.

Writes ``OUT.csv`` and its sidecar ``OUT.json``, then reads them back through the
recording reader so that what was written is known to be valid. Prints one line: the
output, the number of samples and segments.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from api.cli import BadInput, decimal_arg
from bench.convert import read_imu_tk, read_imucal
from bench.recording import Recording, read_recording, write_recording


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench convert``."""
    parser.add_argument("source_format", choices=["imu_tk", "imucal"], help="the tool whose files are given")
    parser.add_argument(
        "sources",
        nargs="+",
        type=Path,
        help="imu_tk: xsens_acc.mat [xsens_gyro.mat] or the joined CSV; "
        "imucal: session.csv [sections.json] or annotated_session.csv",
    )
    parser.add_argument(
        "-o", "--output", type=Path, required=True, help="OUT.csv (the sidecar goes to OUT.json)"
    )
    parser.add_argument(
        "--sample-rate-hz",
        type=decimal_arg,
        help="imucal only, required: the session's sample rate (the files do not carry it)",
    )
    parser.add_argument(
        "--g-local-m-s2", type=decimal_arg, help="local gravity to record (default: the source's own value)"
    )
    parser.add_argument("--force", action="store_true", help="overwrite OUT.csv / OUT.json if they exist")


def _convert(args: argparse.Namespace) -> Recording:
    for s in args.sources:
        if not s.is_file():
            raise BadInput(f"{s}: no such file")
    if args.source_format == "imu_tk":
        if len(args.sources) > 2:
            raise BadInput("imu_tk: give xsens_acc.mat and optionally xsens_gyro.mat, or the joined CSV")
        if args.sample_rate_hz is not None:
            raise BadInput(
                "imu_tk: --sample-rate-hz does not apply (the files carry time stamps; nominal 100 Hz)"
            )
        rec = read_imu_tk(args.sources[0], args.sources[1] if len(args.sources) == 2 else None)
        if args.g_local_m_s2 is not None:
            from dataclasses import replace

            rec = replace(rec, sidecar=replace(rec.sidecar, g_local_m_s2=args.g_local_m_s2))
        return rec
    if args.sample_rate_hz is None:
        raise BadInput(
            "imucal: --sample-rate-hz is required (102.4 for example_ferraris_session.csv, "
            "204.8 for annotated_session.csv)"
        )
    kw = {} if args.g_local_m_s2 is None else {"g_local_m_s2": args.g_local_m_s2}
    return read_imucal(args.sources, args.sample_rate_hz, **kw)


def run(args: argparse.Namespace) -> int:
    """Convert, write, read back; exit 0, or raise for bad input (exit 2)."""
    out: Path = args.output
    if out.suffix.lower() != ".csv":
        raise BadInput(f"{out}: the output must be a .csv file (its sidecar gets the same stem, .json)")
    sidecar = out.with_suffix(".json")
    if not args.force:
        for p in (out, sidecar):
            if p.exists():
                raise BadInput(f"{p}: exists; use --force to overwrite it")
    rec = _convert(args)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_recording(rec, out, overwrite=args.force)
    back = read_recording(out)
    n_seg = len(back.sidecar.segments or ())
    print(f"{out}: {back.n_samples} samples, {n_seg} segments, channel_unit {back.sidecar.channel_unit}")
    return 0
