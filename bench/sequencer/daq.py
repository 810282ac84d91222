"""The DAQ reader thread: drains the DAQ's buffer continuously into a queue.

At 1 kHz the DAQ's ring buffer must be read often, also while the table is executing a
blocking move; so one thread does nothing but ``read_block`` and hands the blocks to the
sequencer through a queue. A :class:`drivers.errors.DataGap` is passed on as a
:class:`Gap` (the sequencer re-records the window it spoiled) and reading goes on; any other
error is passed on and ends the thread.

A reader that fell behind a fast DAQ can keep losing the race for the oldest samples in the
ring (each read starts at a sample about to be overwritten). After ``restart_after_gaps``
consecutive gaps the pump restarts acquisition (``stop()``, ``start()``: the DAQ's counter and
clock restart at 0) and says so with :class:`Restarted`, with the samples it knows were lost
by it, so the recording clock is re-based and the restart recorded as a gap.

A read that timed out (a lost reply) consumed nothing (``Daq.read_block``'s contract), so
it is retried, up to ``max_read_failures`` times in a row; what the ring overwrote
meanwhile comes back as a gap.

The consumer takes items with :meth:`DaqPump.next_item`, which joins the sample blocks
queued back to back into one (up to ``max_samples``): a fast stream then costs the
sequencer one pass per backlog instead of one per driver read.
"""

from __future__ import annotations

import queue
import threading
from dataclasses import dataclass

import numpy as np

from drivers.base import Daq, SampleBlock
from drivers.errors import DataGap, DeviceTimeout


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
    """Acquisition was restarted after repeated gaps; DAQ time starts again at 0.

    :param gaps: consecutive gaps that led to the restart.
    :param next_seq: the sequence number the reader expected next in the old epoch
        (``None`` if the DAQ's status does not say).
    :param unread: samples the old epoch produced that were never read (``None``: unknown).
    """

    gaps: int
    next_seq: int | None = None
    unread: int | None = None


Item = SampleBlock | Gap | Failed | Restarted


class DaqPump:
    """Reads ``daq`` in a background thread until :meth:`stop`.

    :param daq: a started or unstarted DAQ (``start()`` is called by :meth:`start`).
    :param max_samples: samples per read.
    :param read_timeout_s: per-read timeout.
    :param restart_after_gaps: consecutive gaps after which acquisition is restarted.
    :param max_read_failures: consecutive timed-out reads retried before the DAQ counts as failed.
    :param idle_wait_s: wait (wall s) after a read that found the DAQ's buffer nearly empty
        (fewer than ``max_samples / 8``): samples gather into one block per read instead of
        a request per fresh sample, which would cost most of a core in round trips whatever
        the data rate. Keep it far below the time the DAQ's ring takes to fill.
    """

    def __init__(
        self,
        daq: Daq,
        max_samples: int,
        read_timeout_s: float,
        restart_after_gaps: int = 3,
        idle_wait_s: float = 0.0,
        max_read_failures: int = 3,
    ) -> None:
        self.daq = daq
        self.stop_error: BaseException | None = None
        """Why stopping the DAQ failed (:meth:`stop`), if it did."""
        self.max_samples = max_samples
        self.read_timeout_s = read_timeout_s
        self.idle_wait_s = idle_wait_s
        self.restart_after_gaps = restart_after_gaps
        self.max_read_failures = max_read_failures
        self.items: queue.Queue[Item] = queue.Queue()
        self._pending: Item | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="daq-pump", daemon=True)

    def start(self) -> None:
        """Start acquisition and the reader thread."""
        self.daq.start()
        self._thread.start()

    def _loop(self) -> None:
        gaps = 0
        failures = 0
        while not self._stop.is_set():
            try:
                block = self.daq.read_block(self.max_samples, self.read_timeout_s)
            except DataGap as exc:
                self.items.put(Gap(exc))
                gaps += 1
                if gaps >= self.restart_after_gaps:
                    try:
                        restarted = self._restart(gaps)
                    except BaseException as restart_exc:
                        self.items.put(Failed(restart_exc))
                        return
                    self.items.put(restarted)
                    gaps = 0
                continue
            except DeviceTimeout as exc:
                failures += 1
                if failures > self.max_read_failures:
                    self.items.put(Failed(exc))
                    return
                continue
            except BaseException as exc:
                self.items.put(Failed(exc))
                return
            gaps = failures = 0
            if block.n:
                self.items.put(block)
            if block.n < self.max_samples // 8:
                # Caught up: let samples gather instead of one request per fresh sample
                # (a reader with a backlog reads on at once).
                self._stop.wait(max(self.idle_wait_s, 0.002 if not block.n else 0.0))

    def _restart(self, gaps: int) -> Restarted:
        """Stop acquisition, count what the old epoch produced and nobody read, start again.

        The count is read after the stop, so it is exact: ``counter − next expected``.
        """
        self.daq.stop()
        next_seq = unread = None
        try:
            st = self.daq.status()
            n, fill = st.get("next_seq"), st.get("buffer_fill")
            next_seq = n if isinstance(n, int) else None
            unread = fill if isinstance(fill, int) else None
        except Exception:  # the count is a courtesy; the restart is what matters
            pass
        self.daq.start()
        return Restarted(gaps, next_seq, unread)

    def next_item(self, wait_s: float, max_samples: int) -> Item | None:
        """The next item (``None`` if none came within ``wait_s``); consecutive queued blocks
        are joined into one of at most ``max_samples`` samples (a single larger block is kept whole).
        """
        item = self._pending
        self._pending = None
        if item is None:
            try:
                item = self.items.get(timeout=wait_s)
            except queue.Empty:
                return None
        if not isinstance(item, SampleBlock):
            return item
        blocks, n = [item], item.n
        while n < max_samples:
            try:
                nxt = self.items.get_nowait()
            except queue.Empty:
                break
            if not isinstance(nxt, SampleBlock) or n + nxt.n > max_samples:
                self._pending = nxt
                break
            blocks.append(nxt)
            n += nxt.n
        return join_blocks(blocks)

    def drain(self) -> list[Item]:
        """Every item still queued (after :meth:`stop`), in order."""
        out: list[Item] = [] if self._pending is None else [self._pending]
        self._pending = None
        while True:
            try:
                out.append(self.items.get_nowait())
            except queue.Empty:
                return out

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
            self.stop_error = exc
            problem = f"DAQ stop failed: {type(exc).__name__}: {exc}"
        return problem


def join_blocks(blocks: list[SampleBlock]) -> SampleBlock:
    """One block of consecutive blocks (no gap between them: the driver reports gaps as items)."""
    if len(blocks) == 1:
        return blocks[0]
    tables = [b.table_deg for b in blocks if b.table_deg is not None]
    flags = tuple(sorted({f for b in blocks for f in b.flags}))
    return SampleBlock(
        blocks[0].first_seq,
        np.concatenate([b.t_s for b in blocks]),
        np.concatenate([b.accel for b in blocks]),
        np.concatenate([b.temp_c for b in blocks]),
        np.concatenate(tables) if len(tables) == len(blocks) else None,
        flags,
    )
