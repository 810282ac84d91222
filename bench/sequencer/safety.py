"""Getting the table ready before a run and safe after it, whatever happened.

The :class:`drivers.base.RotaryTable` protocol only promises ``stop()``; a table driver that
also offers ``prepare(timeout_s)`` (clear faults, close interlocks, position mode) and
``make_safe(timeout_s)`` (stop, wait for rest, motors off, interlock open: the shutdown order
of the table research) gets them called. Every safe-state command runs under a deadline, so
a table that no longer answers cannot hang the end of a run; what failed is reported.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bench.sequencer.context import RunContext
from bench.sequencer.deadline import call_with_deadline
from drivers.base import RotaryTable
from drivers.errors import DeviceTimeout


def optional_table_method(table: RotaryTable, name: str) -> Callable[..., Any] | None:
    """The table driver's ``prepare`` or ``make_safe`` if it offers one, else ``None``.

    Neither is part of the :class:`RotaryTable` protocol: a table without them is used as it is.
    """
    method = getattr(table, name, None)
    return method if callable(method) else None


def prepare_table(seq: RunContext) -> None:
    """Ready the table, through its optional ``prepare(timeout_s)`` (clear faults, close interlocks),
    before the DAQ runs (no samples to drain yet)."""
    prepare = optional_table_method(seq.table, "prepare")
    if prepare is not None:
        seq.where = "preparing the table"
        timeout = seq.config.move_timeout_margin_s
        call_with_deadline(lambda: prepare(timeout), timeout + seq.config.stop_timeout_s, "prepare")


def make_safe(seq: RunContext) -> list[str]:
    """Table stopped, acquisition stopped, recording closed; return what failed."""
    problems: list[str] = []
    try:
        call_with_deadline(lambda: _stop_table(seq, problems), seq.config.stop_timeout_s, "safe state")
    except DeviceTimeout as exc:
        seq.safe_faults.append(exc)
        problems.append(f"table did not confirm stop within {seq.config.stop_timeout_s:g} s")
    # Samples still queued belong to the recording too.
    problems += seq.finish_acquisition()
    try:
        chunk = seq.recorder.close()
        if chunk is not None:
            seq.notify("on_chunk", seq.start.run_id, chunk)
    except Exception as exc:
        seq.safe_faults.append(exc)
        problems.append(f"closing the recording failed: {type(exc).__name__}: {exc}")
    return problems


def _stop_table(seq: RunContext, problems: list[str]) -> None:
    """The table's ``make_safe(timeout_s)`` if it has one (stop, motors off, interlock off), else stop."""
    make_safe_ = optional_table_method(seq.table, "make_safe")
    try:
        if make_safe_ is not None:
            make_safe_(seq.config.stop_timeout_s)
        else:
            seq.table.stop()
    except Exception as exc:
        seq.safe_faults.append(exc)
        problems.append(f"table safe state failed: {type(exc).__name__}: {exc}")
