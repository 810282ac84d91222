"""``calbench run PROCEDURE --unit SERIAL [--sim] [--sim-speed N]``: run a procedure on the bench.

Shows a progress bar on stderr while the run records, then prints the fit and the |g|
table (or, with ``--json``, one object: run id, state, outcome, error, calibration). Ctrl-C
aborts the run cleanly (table to its safe state, recording kept). A device fault the bench
recovers from — mid-run or before the first window, the devices not answering when the run
starts — leaves the run stored ``interrupted`` and resumes it automatically
(:mod:`station.execution.fault_retry`); a run still interrupted after the last try (or a
Ctrl-C during a wait) is kept so, and the command names the device, the fault, what is kept
and the ``calbench resume`` command that continues it. Exit code 0 for PASS (or a fit no
limits judged: no statement of conformity), 1 for FAIL, ERROR or ABORTED, 2 for bad input, 3
when another process drives the bench (an agent, another ``calbench run``: one line names it;
:mod:`station.execution.bench_lock`), 4 for a run kept ``interrupted`` (:data:`INTERRUPTED_EXIT`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import signal
import sys
from pathlib import Path
from types import FrameType
from typing import Any, TextIO

from api.cli import decimal_arg
from bench.limits import describe
from bench.procedures import PROCEDURES
from bench.records import Progress, RunRecord, StateChange
from bench.run_observer import NullObserver
from bench.run_state import RunState
from bench.sequencer.control import RunControl
from station.execution.bench_lock import HELD_EXIT, BenchHeld, BenchLock
from station.execution.continuation import resume_run
from station.execution.fault_retry import NeverStarted, run_resuming
from station.execution.session import start_run
from station.settings import Settings

INTERRUPTED_EXIT = 4
"""Exit code of a run kept ``interrupted`` by a device fault: resumable, nothing recorded lost."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench run``."""
    parser.add_argument("procedure", choices=sorted(PROCEDURES), help="procedure to run")
    parser.add_argument("--unit", required=True, metavar="SERIAL", help="serial of the unit under test")
    add_device_arguments(parser)
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulated unit and noise (--sim)")
    parser.add_argument(
        "--dwell-s",
        type=decimal_arg,
        default=None,
        help="static dwell per pose (s); default: from a noise window the run records first",
    )


def add_device_arguments(parser: argparse.ArgumentParser) -> None:
    """``--sim``, ``--sim-speed``, ``--json`` (shared with ``calbench resume``)."""
    parser.add_argument("--sim", action="store_true", help="simulated bench, real drivers")
    parser.add_argument(
        "--sim-speed",
        type=decimal_arg,
        default=None,
        metavar="N",
        help="simulated seconds per wall second (default CALBENCH_SIM_SPEED)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object at the end")
    add_bench_file_argument(parser)


def add_bench_file_argument(parser: argparse.ArgumentParser) -> None:
    """``--bench-file PATH`` (shared with ``calbench resume`` and ``calbench serve``)."""
    parser.add_argument(
        "--bench-file",
        default=None,
        metavar="PATH",
        help="the bench's configuration file (calbench-bench/1, TOML or JSON; default CALBENCH_BENCH_FILE, "
        "else the simulated bench's)",
    )


def settings_for(args: argparse.Namespace) -> Settings:
    """Settings from the environment, with ``--bench-file`` when given."""
    settings = Settings()
    path = getattr(args, "bench_file", None)
    return settings if path is None else settings.model_copy(update={"bench_file": Path(path)})


class ProgressBar(NullObserver):
    """A one-line progress bar on a text stream (stderr)."""

    def __init__(self, stream: TextIO | None = None, width: int = 30) -> None:
        self.stream = stream or sys.stderr
        self.width = width

    def _write(self, text: str) -> None:
        self.stream.write(text)
        self.stream.flush()

    def on_progress(self, run_id: str, progress: Progress) -> None:
        done = int(progress.fraction * self.width)
        w = progress.window_index
        win = "" if w is None else f" window {w + 1}/{progress.n_windows}"
        self._write(
            f"\r[{'#' * done}{'.' * (self.width - done)}] {progress.fraction:5.1%} "
            f"step {progress.step_index + 1}/{progress.n_steps} {progress.step_label}{win}   "
        )

    def on_state(self, run_id: str, change: StateChange) -> None:
        self._write(f"\n{change.state.value}: {change.reason}\n")

    def on_finish(self, record: RunRecord) -> None:
        self._write("\n")


def resume_command(args: argparse.Namespace, run_id: str) -> str:
    """The ``calbench resume`` command that continues ``run_id`` on the bench ``args`` name."""
    words = ["calbench", "resume", run_id]
    if getattr(args, "sim", False):
        words.append("--sim")
    if getattr(args, "bench_file", None) is not None:
        words += ["--bench-file", shlex.quote(str(args.bench_file))]
    return " ".join(words)


def never_started_as_dict(result: NeverStarted, resume: str) -> dict[str, Any]:
    """The ``--json`` object of a run whose devices never opened (nothing recorded)."""
    return {
        "run_id": result.run_id,
        "state": RunState.INTERRUPTED.value,
        "outcome": None,
        "error": result.error,
        "recording": None,
        "n_samples": 0,
        "n_windows": 0,
        "resume_command": resume,
    }


def record_as_dict(record: RunRecord, resume: str | None = None) -> dict[str, Any]:
    """The JSON object printed by ``--json`` (``resume``: the command that continues an
    interrupted run)."""
    dwell = record.dwell
    return {
        "run_id": record.run_id,
        "state": record.state.value,
        "outcome": record.outcome.value if record.outcome else None,
        "conformity_note": record.conformity_note or None,
        "error": record.error,
        "recording": record.start.recording_path,
        "n_samples": record.n_samples,
        "n_windows": len(record.windows),
        "dwell": None
        if dwell is None
        else {"dwell_s": dwell.dwell_s, "source": dwell.source, "reason": dwell.reason},
        "calibration": None if record.calibration is None else record.calibration.to_contract(),
        "limit_checks": [dataclasses.asdict(c) for c in record.limit_checks],
        **({"resume_command": resume} if record.state is RunState.INTERRUPTED and resume else {}),
    }


def report_interrupted(result: RunRecord | NeverStarted, as_json: bool, resume: str) -> int:
    """Print a run kept ``interrupted``: the device and the fault, what is kept, how to resume."""
    if as_json:
        obj = (
            never_started_as_dict(result, resume)
            if isinstance(result, NeverStarted)
            else record_as_dict(result, resume)
        )
        print(json.dumps(obj, indent=1))
        return INTERRUPTED_EXIT
    print(f"run {result.run_id}: interrupted ({result.error})")
    if isinstance(result, NeverStarted):
        print("nothing was recorded: the devices never answered; the run is stored as it was requested")
    else:
        print(
            f"recording: {result.start.recording_path} ({result.n_samples} samples, "
            f"{len(result.windows)} complete windows kept)"
        )
    print(f"the run is kept interrupted; once the bench answers, resume it with: {resume}")
    return INTERRUPTED_EXIT


def report(record: RunRecord | NeverStarted, as_json: bool, resume: str = "calbench resume RUN_ID") -> int:
    """Print the outcome, the fit and the |g| table; return the exit code. A run kept
    ``interrupted`` is reported by :func:`report_interrupted` (``resume``: its command)."""
    if isinstance(record, NeverStarted) or record.state is RunState.INTERRUPTED:
        return report_interrupted(record, as_json, resume)
    if as_json:
        print(json.dumps(record_as_dict(record), indent=1))
        return exit_code(record)
    outcome = record.outcome.value if record.outcome else record.conformity_note or record.state.value
    print(f"run {record.run_id}: {outcome}" + (f" ({record.error})" if record.error else ""))
    print(
        f"recording: {record.start.recording_path} ({record.n_samples} samples, "
        f"{len(record.windows)} windows)"
    )
    if record.dwell is not None:
        print(f"dwell: {record.dwell.reason}")
    if record.calibration is not None:
        fit = record.calibration.fitted_model()
        pairs = zip(fit.bias.tolist(), fit.bias_sigma.tolist(), strict=True)
        print("bias:", "  ".join(f"{b:.6g} ± {s:.2g}" for b, s in pairs))
        print("scale matrix K (channel unit per m/s²):")
        for row, srow in zip(fit.K.tolist(), fit.K_sigma.tolist(), strict=True):
            print("   " + "  ".join(f"{k:+.6e} ± {s:.1e}" for k, s in zip(row, srow, strict=True)))
        print(f"{'|g| check':12s} {'mean error (m/s²)':>18s} {'std (m/s²)':>12s}")
        for name, g in (("before", fit.g_before), ("after", fit.g_after)):
            if g is not None:
                print(f"{name:12s} {g.mean_error_m_s2:18.3e} {g.std_m_s2:12.3e}")
    if record.limit_checks:
        bad = [c for c in record.limit_checks if not c.passed]
        print(
            f"limits: {len(record.limit_checks) - len(bad)}/{len(record.limit_checks)} within"
            + "".join(f"\n  OUT {describe(c)}" for c in bad)
        )
    return exit_code(record)


def exit_code(record: RunRecord) -> int:
    """0 for a completed run (PASS, or a fit no limits judged), 4 for one kept interrupted, else 1."""
    if record.state is RunState.INTERRUPTED:
        return INTERRUPTED_EXIT
    return 0 if record.state is RunState.COMPLETED else 1


def install_abort_handler(control: RunControl) -> None:
    """Ctrl-C / SIGTERM abort the run cleanly (safe state, recording kept) instead of killing it."""

    def handler(signum: int, frame: FrameType | None) -> None:
        control.abort(f"signal {signal.Signals(signum).name}")

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


def holding_bench(settings: Settings, command: str, sim: bool = False) -> BenchLock | None:
    """This process's hold on the bench and its bench file's real devices (none with ``sim``)
    (:class:`~station.execution.bench_lock.BenchLock`), or ``None`` after printing one line
    naming the process that drives it."""
    try:
        return BenchLock(settings, command, sim=sim).acquire()
    except BenchHeld as exc:
        print(f"{command}: {exc}", file=sys.stderr)
        return None


def run(args: argparse.Namespace) -> int:
    """Execute ``calbench run``."""
    settings = settings_for(args)
    lock = holding_bench(settings, "calbench run", sim=args.sim)
    if lock is None:
        return HELD_EXIT
    try:
        return _run(args, settings)
    finally:
        lock.release()


def _run(args: argparse.Namespace, settings: Settings) -> int:
    control = RunControl()
    install_abort_handler(control)
    observers = [] if args.json else [ProgressBar()]
    record = run_resuming(
        lambda: start_run(
            settings,
            args.procedure,
            args.unit,
            sim=args.sim,
            sim_speed=args.sim_speed,
            seed=args.seed,
            dwell_s=args.dwell_s,
            observers=observers,
            control=control,
        ),
        lambda run_id: resume_run(
            settings, run_id, sim=args.sim, sim_speed=args.sim_speed, observers=observers, control=control
        ),
        control,
        say=lambda msg: print(f"calbench run: {msg}", file=sys.stderr),
    )
    return report(record, args.json, resume_command(args, record.run_id))
