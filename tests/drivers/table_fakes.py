"""Test doubles for the table tests: a hand-driven clock and a scripted transport."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager

from drivers.table import SerialRotaryTable


class ManualClock:
    """A SimClock stand-in whose time moves only when the test says so."""

    def __init__(self, t0_s: float = 0.0) -> None:
        self.t = t0_s

    def now_s(self) -> float:
        return self.t

    def advance(self, dt_s: float) -> None:
        self.t += dt_s

    def sleep(self, sim_s: float) -> None:
        self.t += sim_s


Reply = str | Exception


class ScriptedTransport:
    """Plays (expected command, reply) pairs; a wrong or extra command fails the test."""

    def __init__(self, pairs: Sequence[tuple[str, Reply]]) -> None:
        self.pairs = list(pairs)
        self.closed = False

    def query(self, line: str, timeout_s: float) -> str:
        assert self.pairs, f"unexpected extra command {line!r}"
        expected, reply = self.pairs.pop(0)
        assert line == expected, f"sent {line!r}, expected {expected!r}"
        assert timeout_s > 0
        if isinstance(reply, Exception):
            raise reply
        return reply

    def close(self) -> None:
        self.closed = True


@contextmanager
def expected_protocol(pairs: Sequence[tuple[str, Reply]], n_axes: int = 3) -> Iterator[SerialRotaryTable]:
    """pymeasure-style: the driver must send exactly ``pairs``, in order, and nothing else."""
    transport = ScriptedTransport(pairs)
    table = SerialRotaryTable("scripted://", transport=transport, n_axes=n_axes, poll_interval_s=0.0)
    yield table
    assert transport.pairs == [], f"commands never sent: {transport.pairs}"
