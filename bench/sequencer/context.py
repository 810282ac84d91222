"""What the step logic and the safe-state logic may use of a running sequencer.

:mod:`bench.sequencer.steps` and :mod:`bench.sequencer.safety` work on a :class:`RunContext`,
not on the :class:`~bench.sequencer.loop.Sequencer` class: the loop owns its DAQ pump, its
clocks and its flags, and offers these members instead. A test can hand them any object that
has them.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Protocol, TypeVar

from bench.procedures.steps import Procedure
from bench.records import DwellChoice, RunStart, WindowRecord
from bench.run_recorder import RunRecorder
from bench.run_state import RunState
from bench.sequencer.control import RunControl, SequencerConfig
from bench.sequencer.window import WindowCollector
from drivers.base import Daq, RotaryTable

T = TypeVar("T")


class RunContext(Protocol):
    """The run being executed: its devices, plan, configuration and the loop's services."""

    table: RotaryTable
    daq: Daq
    procedure: Procedure
    recorder: RunRecorder
    start: RunStart
    control: RunControl
    config: SequencerConfig
    dwell: DwellChoice | None
    start_window: int
    next_window: int
    step_index: int
    where: str
    window: WindowCollector | None
    positions_deg: tuple[float, ...]
    last_temp_c: float
    now_s: float
    """The recording clock (s)."""
    held_s: float
    """Recording-clock time of the holds that have ended (s)."""
    hold_began_s: float | None
    """The recording clock when the hold in progress began (``None``: not held)."""
    safe_faults: list[BaseException]
    """What failed while making the table and acquisition safe at the end (exceptions)."""

    def notify(self, method: str, *args: object) -> None:
        """Tell every observer (``method`` of :class:`bench.run_observer.RunObserver`)."""

    def set_state(self, state: RunState, reason: str = "") -> None:
        """Change the run's state and tell the observers."""

    def progress(self, force: bool = False) -> None:
        """Emit a progress event (rate-limited unless ``force``)."""

    def pump_once(self, wait_s: float = 0.05) -> None:
        """Handle at most one DAQ item and check abort, pause, stall and interlock."""

    def wait_data(self, duration_s: float) -> None:
        """Keep recording for ``duration_s`` on the recording clock."""

    def call(self, fn: Callable[[], T], deadline_s: float, what: str) -> T:
        """A blocking table call under a deadline, the DAQ drained meanwhile."""

    def record_window(self, collector: WindowCollector) -> WindowRecord:
        """Record a window to its end and close it in the recording."""

    def check_table(self) -> None:
        """Poll the table now: an open interlock or E-stop suspends the run."""

    def holding(self) -> AbstractContextManager[None]:
        """While held: no pause, interlock or temperature interruption is raised by the loop."""

    def status_due(self) -> bool:
        """Whether the table's status is due for a poll; marks it polled when it is."""

    def poll_status_soon(self) -> None:
        """Make the next :meth:`status_due` true (after a resume, check the interlock now)."""

    def finish_acquisition(self) -> list[str]:
        """Stop the DAQ, record the samples still queued; return what failed."""
