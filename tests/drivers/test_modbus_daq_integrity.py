"""No sample skipped unseen: a gap met in the middle of a read, a host stall between two
window reads and lost Modbus replies are all either delivered later or reported as DataGap."""

from __future__ import annotations

import time

import pytest

from drivers.errors import DataGap, DeviceTimeout
from tests.drivers.test_modbus_daq import sim_daq

pytestmark = pytest.mark.timeout(60)


def test_a_gap_after_samples_in_one_call_is_raised_by_the_next_call() -> None:
    with sim_daq(rate_hz=200.0, speed=5.0) as rig:
        rig.daq.start()
        time.sleep(0.1)  # ~100 samples before the drop
        rig.engine.update()
        before = rig.engine.counter
        rig.server.drop_samples(37)
        time.sleep(0.1)  # more samples after it
        rig.engine.update()
        block = rig.daq.read_block(100_000, timeout_s=1.0)
        assert (block.first_seq, block.n) == (0, before)  # everything before the hole...
        with pytest.raises(DataGap) as info:  # ...then the hole itself, never folded away
            rig.daq.read_block(100_000, timeout_s=1.0)
        assert (info.value.expected_seq, info.value.n_lost, info.value.cause) == (before, 37, "dropped")
        after = rig.daq.read_block(100_000, timeout_s=1.0)
        assert after.first_seq == before + 37


def test_a_host_stall_between_two_window_reads_is_reported_as_an_overflow_gap() -> None:
    with sim_daq(rate_hz=1000.0, speed=1.0, ring_capacity=600, timeout_s=2.0) as rig:
        rig.daq.start()
        time.sleep(0.4)  # a backlog of several windows (120 samples each)
        real = rig.daq._read_window
        calls = {"n": 0}

        def stalling(want: int, deadline: float):  # type: ignore[no-untyped-def]
            calls["n"] += 1
            if calls["n"] == 2:
                time.sleep(1.0)  # the host stalls: ~1000 samples, the ring keeps 600
            return real(want, deadline)

        rig.daq._read_window = stalling  # type: ignore[method-assign]
        block = rig.daq.read_block(100_000, timeout_s=5.0)
        assert block.first_seq == 0 and block.n == 120  # the window read before the stall
        with pytest.raises(DataGap) as info:
            rig.daq.read_block(100_000, timeout_s=5.0)
        gap = info.value
        assert gap.expected_seq == 120 and gap.cause == "overflow"
        rig.engine.update()
        assert gap.got_seq > rig.engine.counter - 600  # only what the ring could not keep, and more
        after = rig.daq.read_block(100_000, timeout_s=5.0)
        assert after.first_seq == gap.got_seq


def test_a_lost_reply_in_the_middle_of_a_read_consumes_nothing() -> None:
    with sim_daq(rate_hz=1000.0, speed=2.0, timeout_s=0.2) as rig:
        rig.daq.start()
        first = rig.daq.read_block(10, timeout_s=1.0)
        time.sleep(0.3)  # a backlog of ~600 samples: several windows
        rig.server.drop_replies(1, after=25)  # the first window (~18 replies) arrives, then one is lost
        with pytest.raises(DeviceTimeout):
            rig.daq.read_block(100_000, timeout_s=2.0)
        again = rig.daq.read_block(100_000, timeout_s=2.0)
        assert again.first_seq == first.first_seq + first.n  # the window read before is not skipped
        assert again.n > 120
