"""``calbench convert {imu_tk,imucal} SOURCE... -o OUT.csv``: another tool's data set as calbench-recording/1.

Writes ``OUT.csv`` and its sidecar ``OUT.json``, then reads them back through the
recording reader so that what was written is known to be valid. Prints one line: the
output, the number of samples and segments.

A converter writes only what the source files say. For ``imu_tk`` the files carry time
stamps and numbers, nothing else: the accelerometer's unit (``--channel-unit``, except for
the joined CSV whose header names counts), the gyro's unit (``--gyro-unit``, with a gyro
file) and local gravity (``--g-local-m-s2``) must be given, or the command exits 2 naming
the option; the unit's model and serial and the data set's credit are written only when
given (``--unit-model``, ``--unit-serial``, ``--dataset``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from api.cli import BadInput, decimal_arg
from bench.convert import read_imu_tk, read_imucal
from bench.convert.imu_tk import CHANNEL_UNITS, GYRO_UNITS, XSENS_G_LOCAL_M_S2
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
        "--g-local-m-s2",
        type=decimal_arg,
        help="local gravity to record; imu_tk: required (the files do not carry it; "
        f"{XSENS_G_LOCAL_M_S2} for IMU-TK's Xsens data set); imucal: default the source's own value",
    )
    parser.add_argument(
        "--channel-unit",
        choices=CHANNEL_UNITS,
        help="imu_tk: unit of the accelerometer numbers (required for the .mat text files)",
    )
    parser.add_argument(
        "--gyro-unit", choices=GYRO_UNITS, help="imu_tk: unit of the gyro numbers (required with a gyro file)"
    )
    parser.add_argument("--unit-model", help="imu_tk: the unit's model (written only when given)")
    parser.add_argument("--unit-serial", help="imu_tk: the unit's serial number (default 'unknown')")
    parser.add_argument("--dataset", help="imu_tk: which data set the files come from, to credit it")
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
                "imu_tk: --sample-rate-hz does not apply (the rate is the time stamps' median spacing)"
            )
        joined = args.sources[0].suffix.lower() == ".csv"
        if args.channel_unit is None and not joined:
            raise BadInput(
                f"imu_tk: --channel-unit is required: {args.sources[0].name} does not say the "
                f"accelerometer's unit ({', '.join(CHANNEL_UNITS)})"
            )
        if len(args.sources) == 2 and args.gyro_unit is None:
            raise BadInput(
                f"imu_tk: --gyro-unit is required: {args.sources[1].name} does not say the gyro's unit "
                f"({', '.join(GYRO_UNITS)})"
            )
        if args.g_local_m_s2 is None:
            raise BadInput(
                "imu_tk: --g-local-m-s2 is required: the files do not carry local gravity "
                f"({XSENS_G_LOCAL_M_S2} for IMU-TK's own Xsens data set)"
            )
        return read_imu_tk(
            args.sources[0],
            args.sources[1] if len(args.sources) == 2 else None,
            channel_unit=args.channel_unit,
            g_local_m_s2=args.g_local_m_s2,
            gyro_unit=args.gyro_unit,
            unit_model=args.unit_model,
            unit_serial=args.unit_serial or "unknown",
            dataset=args.dataset,
        )
    given = [
        opt
        for opt, v in (
            ("--channel-unit", args.channel_unit),
            ("--gyro-unit", args.gyro_unit),
            ("--unit-model", args.unit_model),
            ("--unit-serial", args.unit_serial),
            ("--dataset", args.dataset),
        )
        if v is not None
    ]
    if given:
        raise BadInput(f"imucal: {', '.join(given)} apply to imu_tk only")
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
