"""Getting the table ready before a run and safe after it, whatever happened.

The :class:`drivers.base.RotaryTable` protocol only promises ``stop()``; a table driver that
also offers ``prepare(timeout_s)`` (clear faults, close interlocks, position mode) and
``make_safe(timeout_s)`` (stop, wait for rest, motors off, interlock open: the shutdown order
of the table research) gets them called. Every safe-state command runs under a deadline, so
a table that no longer answers cannot hang the end of a run; what failed is reported.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from bench.sequencer_daq import Gap, Restarted
from drivers.base import SampleBlock
from drivers.errors import DeviceTimeout

if TYPE_CHECKING:
    from bench.sequencer import Sequencer


def prepare_table(seq: Sequencer) -> None:
    """Ready the table, through its optional ``prepare(timeout_s)`` (clear faults, close interlocks).

    Not part of the :class:`RotaryTable` protocol: a table without it is used as it is.
    """
    prepare = getattr(seq.table, "prepare", None)
    if callable(prepare):
        seq.where = "preparing the table"
        timeout = seq.config.move_timeout_margin_s
        _run_blocking(lambda: prepare(timeout), timeout + seq.config.stop_timeout_s, "prepare")

def _run_blocking(fn: Callable[[], object], deadline_s: float, what: str) -> None:
    """Run ``fn`` in a helper thread before the DAQ runs (no samples to drain yet)."""
    box: dict[str, BaseException] = {}

    def target() -> None:
        try:
            fn()
        except BaseException as exc:
            box["error"] = exc

    worker = threading.Thread(target=target, name=f"table-{what}", daemon=True)
    worker.start()
    worker.join(deadline_s)
    if worker.is_alive():
        raise DeviceTimeout(f"table {what} did not return within {deadline_s:.3g} s")
    if "error" in box:
        raise box["error"]

def make_safe(seq: Sequencer) -> list[str]:
    """Table stopped, acquisition stopped, recording closed; return what failed."""
    problems: list[str] = []
    stopper = threading.Thread(target=_stop_table, args=(seq, problems), daemon=True)
    stopper.start()
    stopper.join(seq.config.stop_timeout_s)
    if stopper.is_alive():
        problems.append(f"table did not confirm stop within {seq.config.stop_timeout_s:g} s")
    pump_problem = seq._pump.stop(seq.config.stop_timeout_s)
    if pump_problem:
        problems.append(pump_problem)
    # Samples still queued belong to the recording too, and so do the gaps between them.
    seq.window = None
    seq._holding = True
    for item in seq._pump.drain() if seq.recorder.failed is None else ():
        try:
            if isinstance(item, Restarted):
                seq._record_restart(item)
            elif isinstance(item, Gap):
                seq._record_gap(item.error)
            elif isinstance(item, SampleBlock):
                seq._handle_block(item)
        except Exception as exc:
            problems.append(f"saving the last samples failed: {exc}")
            break
    try:
        chunk = seq.recorder.close()
        if chunk is not None:
            seq.notify("on_chunk", seq.start.run_id, chunk)
    except Exception as exc:
        problems.append(f"closing the recording failed: {type(exc).__name__}: {exc}")
    return problems

def _stop_table(seq: Sequencer, problems: list[str]) -> None:
    """The table's ``make_safe(timeout_s)`` if it has one (stop, motors off, interlock off), else stop."""
    make_safe = getattr(seq.table, "make_safe", None)
    try:
        if callable(make_safe):
            make_safe(seq.config.stop_timeout_s)
        else:
            seq.table.stop()
    except Exception as exc:
        problems.append(f"table safe state failed: {type(exc).__name__}: {exc}")
