"""The observer protocol: how the database, the service and a progress bar hear of a run.

The sequencer (:mod:`bench.sequencer`) hands every observer the records of
:mod:`bench.records` as the run goes (openhtf's output callbacks); the samples themselves
go to the recording, not through observers.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

from bench.records import (
    ChunkRecord,
    DwellChoice,
    GapRecord,
    Progress,
    RunRecord,
    RunStart,
    StateChange,
    WindowRecord,
)


@runtime_checkable
class RunObserver(Protocol):
    """Receives a run's records as they happen (the database, the service, a progress bar).

    Calls come from the sequencer's thread, in order: ``on_start``, then any number of
    ``on_state`` / ``on_progress`` / ``on_chunk`` / ``on_window``, then ``on_finish``
    exactly once (also after an error or an abort). An observer must not block for long
    (the DAQ buffer is being drained between calls) and should not raise; an exception
    from an observer ends the run as ERROR with the observer named.
    """

    def on_start(self, start: RunStart) -> None:
        """A run starts, or a resumed run starts again (``start.resumed_from_window`` set)."""
        return None

    def on_state(self, run_id: str, change: StateChange) -> None:
        """The run changed state (pause, suspension, resume)."""
        return None

    def on_progress(self, run_id: str, progress: Progress) -> None:
        """Periodic progress (a few times a second at most)."""
        return None

    def on_chunk(self, run_id: str, chunk: ChunkRecord) -> None:
        """A chunk of samples is flushed and fsync'ed to the recording."""
        return None

    def on_window(self, run_id: str, window: WindowRecord) -> None:
        """A window is complete: samples flushed, segment written to the sidecar."""
        return None

    def on_dwell(self, run_id: str, dwell: DwellChoice) -> None:
        """The dwell time was chosen (at the start, or after the noise window)."""
        return None

    def on_finish(self, record: RunRecord) -> None:
        """The run ended (any outcome)."""
        return None

    # Optional: ``on_gap(run_id: str, gap: GapRecord) -> None`` is called, when an observer
    # defines it, as soon as a sample gap is recorded (before the window is re-measured).
    # Optional: ``on_samples(run_id, t_s, accel, table_deg) -> None``: each block once it is
    # recorded, for a live view (:meth:`bench.sequencer.observers.Observers.samples`).
    # Optional: ``on_phase(run_id: str, phase: str) -> None`` (:func:`announce_phase`): the
    # recording is over and the run is ``"analysing"`` (fit, verdict, diagnosis).


class NullObserver(RunObserver):
    """A :class:`RunObserver` that ignores everything (each method is the protocol's own, which
    returns at once); subclass it and override what you need."""

    def on_gap(self, run_id: str, gap: GapRecord) -> None:
        """Ignored (the optional hook of the module's observers)."""


def announce_phase(observers: Sequence[object], run_id: str, phase: str) -> None:
    """Tell every observer that defines the optional ``on_phase(run_id, phase)`` hook that the
    run entered ``phase`` (``"analysing"``: every step is done, the fit and verdict follow)."""
    for obs in observers:
        hook = getattr(obs, "on_phase", None)
        if hook is not None:
            hook(run_id, phase)
