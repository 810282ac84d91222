"""The DAQ reader thread: drains the DAQ's buffer continuously into a queue.

At 1 kHz the DAQ's ring buffer must be read often, also while the table is executing a
blocking move; so one thread does nothing but ``read_block`` and hands the blocks to the
sequencer through a queue. A :class:`drivers.errors.DataGap` is passed on as a
:class:`Gap` (the sequencer re-records the window it spoiled) and reading goes on; any other
error is passed on and ends the thread.

A reader that fell behind a fast DAQ can keep losing the race for the oldest samples in the
ring (each read starts at a sample about to be overwritten). After ``restart_after_gaps``
consecutive gaps the pump restarts acquisition (``stop()``, ``start()``: the DAQ's counter and
clock restart at 0) and says so with :class:`Restarted`, so the recording clock is re-based.
"""

from __future__ import annotations

import queue
import threading
from dataclasses import dataclass

from drivers.base import Daq, SampleBlock
from drivers.errors import DataGap


@dataclass(frozen=True)
class Gap:
    """Samples were lost between two blocks."""

    error: DataGap


@dataclass(frozen=True)
class Failed:
    """The DAQ failed; the thread has stopped."""

    error: BaseException


@dataclass(frozen=True)
class Restarted:
    """Acquisition was restarted after repeated gaps; DAQ time starts again at 0."""

    gaps: int


Item = SampleBlock | Gap | Failed | Restarted


class DaqPump:
    """Reads ``daq`` in a background thread until :meth:`stop`.

    :param daq: a started or unstarted DAQ (``start()`` is called by :meth:`start`).
    :param max_samples: samples per read.
    :param read_timeout_s: per-read timeout.
    """

    def __init__(self, daq: Daq, max_samples: int, read_timeout_s: float,
                 restart_after_gaps: int = 3) -> None:
        self.daq = daq
        self.max_samples = max_samples
        self.read_timeout_s = read_timeout_s
        self.restart_after_gaps = restart_after_gaps
        self.items: queue.Queue[Item] = queue.Queue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="daq-pump", daemon=True)

    def start(self) -> None:
        """Start acquisition and the reader thread."""
        self.daq.start()
        self._thread.start()

    def _loop(self) -> None:
        gaps = 0
        while not self._stop.is_set():
            try:
                block = self.daq.read_block(self.max_samples, self.read_timeout_s)
            except DataGap as exc:
                self.items.put(Gap(exc))
                gaps += 1
                if gaps >= self.restart_after_gaps:
                    try:
                        self.daq.stop()
                        self.daq.start()
                    except BaseException as restart_exc:
                        self.items.put(Failed(restart_exc))
                        return
                    self.items.put(Restarted(gaps))
                    gaps = 0
                continue
            except BaseException as exc:
                self.items.put(Failed(exc))
                return
            gaps = 0
            if block.n:
                self.items.put(block)
            else:
                self._stop.wait(0.002)

    def stop(self, timeout_s: float) -> str | None:
        """Stop the thread and the acquisition; return a problem description or ``None``."""
        self._stop.set()
        problem = None
        if self._thread.is_alive():
            self._thread.join(timeout_s)
            if self._thread.is_alive():
                problem = f"DAQ reader did not stop within {timeout_s:g} s"
        try:
            self.daq.stop()
        except Exception as exc:
            problem = f"DAQ stop failed: {type(exc).__name__}: {exc}"
        return problem
