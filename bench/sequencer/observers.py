"""The observers of one run, told as one: each event goes to every observer in order.

An observer (:class:`bench.run_observer.RunObserver`) should not raise; when one does, the
exception becomes :class:`ObserverError` naming the observer and the event, and the loop
ends the run as ERROR (its records can no longer be trusted to be stored).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

from bench.live_signal import Samples
from bench.records import GapRecord
from bench.run_observer import RunObserver

log = logging.getLogger(__name__)


class ObserverError(Exception):
    """An observer raised; the run cannot be trusted to be stored."""


class Observers:
    """Fans a run's events out to its observers.

    :param observers: told in this order.
    """

    def __init__(self, observers: Sequence[RunObserver]) -> None:
        self._observers = list(observers)
        self._viewers = [obs for obs in self._observers if getattr(obs, "on_samples", None) is not None]

    def notify(self, method: str, *args: object) -> None:
        """Call ``method`` on every observer; an exception becomes :class:`ObserverError`."""
        for obs in self._observers:
            self._call(obs, method, args)

    def gap(self, run_id: str, gap: GapRecord) -> None:
        """Call the optional ``on_gap`` hook of every observer that defines it."""
        for obs in self._observers:
            if getattr(obs, "on_gap", None) is not None:
                self._call(obs, "on_gap", (run_id, gap))

    def samples(self, run_id: str, t_s: Samples, accel: Samples, table_deg: Samples) -> None:
        """Hand a block already recorded to the optional ``on_samples`` hook (a live view:
        ``t_s`` (n,) s, ``accel`` (n, 3), ``table_deg`` (n, n_axes) deg). A view that fails is
        told no more and the run goes on: a viewer never costs the recording a sample."""
        for obs in list(self._viewers):
            try:
                obs.on_samples(run_id, t_s, accel, table_deg)  # type: ignore[attr-defined]
            except Exception:
                log.warning("live view %s failed; it gets no more samples", type(obs).__name__, exc_info=True)
                self._viewers.remove(obs)

    @staticmethod
    def _call(obs: RunObserver, method: str, args: tuple[object, ...]) -> None:
        try:
            getattr(obs, method)(*args)
        except Exception as exc:
            raise ObserverError(
                f"observer {type(obs).__name__}.{method} failed: {type(exc).__name__}: {exc}"
            ) from exc
