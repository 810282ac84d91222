"""The DAQ pump's hand-over: queued blocks joined in order, gaps and restarts kept in place."""

from __future__ import annotations

import numpy as np

from bench.sequencer.daq import DaqPump, Gap, Restarted
from drivers.base import SampleBlock
from drivers.errors import DataGap


def block(first: int, n: int, flags: tuple[str, ...] = (), table: bool = True) -> SampleBlock:
    seq = first + np.arange(n)
    return SampleBlock(
        first,
        seq / 100.0,
        np.column_stack([seq, seq + 0.5, seq + 0.25]).astype(float),
        20.0 + seq / 1e3,
        np.column_stack([seq, -seq]).astype(float) if table else None,
        flags,
    )


def pump_with(*items: object) -> DaqPump:
    pump = DaqPump(daq=None, max_samples=10, read_timeout_s=1.0)  # type: ignore[arg-type]
    for it in items:
        pump.items.put(it)  # type: ignore[arg-type]
    return pump


def test_consecutive_blocks_are_joined_up_to_the_limit_and_stop_at_a_gap() -> None:
    gap = Gap(DataGap(30, 40))
    pump = pump_with(
        block(0, 10),
        block(10, 10, ("over_range:ax",)),
        block(20, 10),
        block(30, 5),
        gap,
        block(40, 7),
        Restarted(3),
        block(0, 4),
    )
    first = pump.next_item(0.0, 25)
    assert isinstance(first, SampleBlock)
    assert first.first_seq == 0 and first.n == 20  # a third block would exceed 25
    np.testing.assert_array_equal(first.accel[:, 0], np.arange(20))
    np.testing.assert_array_equal(first.table_deg, np.column_stack([np.arange(20), -np.arange(20)]))
    np.testing.assert_array_equal(first.t_s, np.arange(20) / 100.0)
    assert first.flags == ("over_range:ax",)
    second = pump.next_item(0.0, 25)
    assert isinstance(second, SampleBlock) and second.first_seq == 20 and second.n == 15
    assert pump.next_item(0.0, 25) is gap
    third = pump.next_item(0.0, 25)
    assert isinstance(third, SampleBlock) and third.first_seq == 40 and third.n == 7
    assert isinstance(pump.next_item(0.0, 25), Restarted)
    assert pump.next_item(0.0, 25).first_seq == 0  # type: ignore[union-attr]
    assert pump.next_item(0.0, 25) is None


def test_a_block_without_encoder_angles_joins_to_none_and_drain_keeps_order() -> None:
    pump = pump_with(block(0, 3), block(3, 3, table=False), Restarted(3), block(0, 2))
    joined = pump.next_item(0.0, 100)
    assert isinstance(joined, SampleBlock) and joined.n == 6 and joined.table_deg is None
    rest = pump.drain()
    assert [type(x).__name__ for x in rest] == ["Restarted", "SampleBlock"]
