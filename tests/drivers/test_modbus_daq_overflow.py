"""After a ring overflow the driver resynchronises once: one DataGap names the lost range."""

from __future__ import annotations

import time

from drivers.errors import DataGap
from tests.drivers.test_modbus_daq import sim_daq


def test_an_overflow_is_one_gap_then_the_reader_continues_half_a_ring_behind_the_newest() -> None:
    with sim_daq(rate_hz=500.0, speed=1.0, ring_capacity=500, timeout_s=2.0) as rig:
        rig.daq.start()
        first = rig.daq.read_block(10_000, timeout_s=1.0)
        expected = first.first_seq + first.n
        time.sleep(1.6)  # ~800 samples produced, the ring keeps 500
        rig.engine.update()
        counter_before = rig.engine.counter
        try:
            rig.daq.read_block(10_000, timeout_s=1.0)
            raise AssertionError("no DataGap after an overflow")
        except DataGap as gap:
            assert gap.expected_seq == expected
            # not the oldest sample (about to be overwritten) but half a ring behind the newest
            assert gap.got_seq >= counter_before - 250
            resumed_at = gap.got_seq
        got = 0
        seq = resumed_at
        while got < 300:  # the reader catches up without another gap
            b = rig.daq.read_block(10_000, timeout_s=1.0)
            assert b.first_seq == seq
            seq += b.n
            got += b.n


def test_a_backlog_read_returns_within_the_call_time_with_what_it_read() -> None:
    with sim_daq(rate_hz=1000.0, speed=4.0, ring_capacity=8000, timeout_s=2.0) as rig:
        rig.daq.start()
        time.sleep(1.5)  # ~6000 samples waiting: about 850 round trips to read them all
        b = rig.daq.read_block(100_000, timeout_s=0.05)
        rest = rig.daq.read_block(100_000, timeout_s=5.0)
        assert 0 < b.n < 6000  # handed over part of the backlog, not all of it...
        assert rest.first_seq == b.first_seq + b.n  # ...and the next call continues after it
