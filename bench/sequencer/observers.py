"""The observers of one run, told as one: each event goes to every observer in order.

An observer (:class:`bench.run_observer.RunObserver`) should not raise; when one does, the
exception becomes :class:`ObserverError` naming the observer and the event, and the loop
ends the run as ERROR (its records can no longer be trusted to be stored).
"""

from __future__ import annotations

from collections.abc import Sequence

from bench.records import GapRecord
from bench.run_observer import RunObserver


class ObserverError(Exception):
    """An observer raised; the run cannot be trusted to be stored."""


class Observers:
    """Fans a run's events out to its observers.

    :param observers: told in this order.
    """

    def __init__(self, observers: Sequence[RunObserver]) -> None:
        self._observers = list(observers)

    def notify(self, method: str, *args: object) -> None:
        """Call ``method`` on every observer; an exception becomes :class:`ObserverError`."""
        for obs in self._observers:
            self._call(obs, method, args)

    def gap(self, run_id: str, gap: GapRecord) -> None:
        """Call the optional ``on_gap`` hook of every observer that defines it."""
        for obs in self._observers:
            if getattr(obs, "on_gap", None) is not None:
                self._call(obs, "on_gap", (run_id, gap))

    @staticmethod
    def _call(obs: RunObserver, method: str, args: tuple[object, ...]) -> None:
        try:
            getattr(obs, method)(*args)
        except Exception as exc:
            raise ObserverError(
                f"observer {type(obs).__name__}.{method} failed: {type(exc).__name__}: {exc}"
            ) from exc
