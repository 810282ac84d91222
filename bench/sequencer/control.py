"""Control of a running sequence from other threads, and the sequencer's settings.

:class:`RunControl` is the thread-safe handle an operator (CLI signal handler, REST route)
uses: :meth:`~RunControl.abort`, :meth:`~RunControl.pause`, :meth:`~RunControl.resume`.
The sequencer polls it between sample blocks, so a request takes effect within one block.
Once every step is done the run is *finishing* (safe state, fit, results): the sequencer asks
:meth:`~RunControl.enter_finishing`, which ends the run ABORTED if an abort came first and
otherwise refuses every later request, so a request either takes effect or is refused.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

from bench.procedures.preview import DEFAULT_TABLE_LIMITS, TableLimits
from bench.run_state import RunState


class AbortRequested(Exception):
    """The operator aborted the run."""


class Interruption(Exception):
    """The current window cannot complete; the run waits, then redoes it.

    :param state: PAUSED (operator) or SUSPENDED (interlock, temperature).
    :param reason: one line for the record.
    """

    def __init__(self, state: RunState, reason: str) -> None:
        self.state = state
        self.reason = reason
        super().__init__(reason)


class WindowSpoiled(Exception):
    """Samples were lost inside a window (DAQ gap); the window is recorded again."""


class RunControl:
    """Thread-safe abort / pause / resume requests for one run."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._abort = threading.Event()
        self._pause = False
        self._resume = threading.Event()
        self._finishing = False
        self.abort_reason = ""
        self.finishing_gate: Callable[[], str | None] | None = None
        """Called once by :meth:`enter_finishing` (the service's: in one database transaction,
        the abort stored for the run, else the run marked finishing so later requests are
        refused): an abort reason, or ``None``."""

    def abort(self, reason: str = "operator abort") -> bool:
        """Stop the run: table to its safe state, recording kept, outcome ABORTED. False (and
        nothing done) once the run is finishing."""
        with self._lock:
            if self._finishing:
                return False
            self.abort_reason = reason
            self._abort.set()
        return True

    def enter_finishing(self) -> str | None:
        """Every step is done: the abort reason if an abort came first (the run then ends
        ABORTED), else ``None`` and from now on abort and pause are refused."""
        reason = self.finishing_gate() if self.finishing_gate is not None else None
        with self._lock:
            if self._abort.is_set():
                return self.abort_reason
            if reason is not None:
                self.abort_reason = reason
                self._abort.set()
                return reason
            self._finishing = True
            self._pause = False
        return None

    @property
    def finishing(self) -> bool:
        """Every step is done and the run is being finished; requests are refused."""
        with self._lock:
            return self._finishing

    def pause(self) -> bool:
        """Hold the run: the window in progress is discarded and recorded again on resume.
        False (and nothing done) once the run is finishing."""
        with self._lock:
            if self._finishing:
                return False
            self._pause = True
        return True

    def resume(self) -> None:
        """Continue a paused run; for a suspended one, the operator's go-ahead: the table is
        prepared again (faults reset, interlocks closed) and the run continues once the
        condition has cleared."""
        with self._lock:
            self._pause = False
        self._resume.set()

    def take_resume_request(self) -> bool:
        """Whether the operator asked to resume since the last call (the request is consumed)."""
        asked = self._resume.is_set()
        self._resume.clear()
        return asked

    def wait_abort(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for an abort; whether one was requested."""
        return self._abort.wait(timeout_s)

    @property
    def abort_requested(self) -> bool:
        """An abort was requested."""
        return self._abort.is_set()

    @property
    def pause_requested(self) -> bool:
        """A pause is in effect."""
        with self._lock:
            return self._pause


@dataclass(frozen=True)
class SequencerConfig:
    """Deadlines and policies of the sequencer (wall-clock seconds unless stated).

    :param limits: the table's limits (move-time estimates, checks).
    :param move_timeout_factor: a move may take this many times its estimated time...
    :param move_timeout_margin_s: ...plus this margin before it is a timeout.
    :param stall_timeout_s: no DAQ samples for this long is a fault (DeviceTimeout).
    :param block_max_samples: samples per DAQ read.
    :param read_timeout_s: timeout of one DAQ read.
    :param daq_idle_wait_s: the DAQ reader's pause after a read that emptied the buffer
        (:class:`bench.sequencer.daq.DaqPump`); 20 ms is 1/400 of a 8192-sample ring at 1 kHz.
    :param status_poll_s: interval of table status polls (interlock) between calls.
    :param progress_interval_s: interval of progress events.
    :param temp_band_c: allowed sensor temperature (°C), ``None``: not watched.
    :param suspend_timeout_s: a suspension or pause longer than this ends the run as ERROR
        (``None``: wait for the operator indefinitely, abort still works).
    :param max_window_retries: a window spoiled more often than this is a fault.
    :param stop_timeout_s: deadline of the safe-state commands at the end.
    :param rest_rate_deg_s: an axis turning slower than this is at rest.
    :param in_position_tol_deg: after a move, samples count as at the target once every
        latched encoder angle is this close to it (deg).
    :param chunk_s: data per durable chunk on the recording clock (s).
    :param min_chunk_wall_s: minimum wall time between chunk flushes.
    """

    limits: TableLimits = DEFAULT_TABLE_LIMITS
    move_timeout_factor: float = 3.0
    move_timeout_margin_s: float = 30.0
    stall_timeout_s: float = 10.0
    block_max_samples: int = 4096
    read_timeout_s: float = 2.0
    daq_idle_wait_s: float = 0.02
    status_poll_s: float = 0.5
    progress_interval_s: float = 0.25
    temp_band_c: tuple[float, float] | None = None
    suspend_timeout_s: float | None = 3600.0
    max_window_retries: int = 3
    stop_timeout_s: float = 10.0
    rest_rate_deg_s: float = 1.0
    in_position_tol_deg: float = 0.05
    chunk_s: float = 1.0
    min_chunk_wall_s: float = 0.2
