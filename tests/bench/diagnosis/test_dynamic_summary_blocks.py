"""The 1 s blocks of the moving-recording summary: a block with too few samples is left out and
every kept sample points at its own block among the kept ones."""

from __future__ import annotations

import numpy as np

from bench.diagnosis.dynamic_summary import _blocks, _bmean
from bench.diagnosis.thresholds import THRESHOLDS


def test_a_short_block_is_dropped_and_the_kept_blocks_are_numbered_without_gaps() -> None:
    # 20 Hz for 2.2 s, then a gap, then 8 s more: block 2 holds 4 samples (< 10) and is left out
    t = np.concatenate([np.arange(44) * 0.05, 5.0 + np.arange(160) * 0.05])
    ids, inv = _blocks(t, np.ones(t.size, dtype=bool), THRESHOLDS.block_s)
    assert ids.tolist() == [0, 1, 5, 6, 7, 8, 9, 10, 11, 12]
    assert inv.min() == -1 and inv.max() == ids.size - 1
    assert np.all(inv[(t >= 2.0) & (t < 3.0)] == -1)  # the 4 samples of the short block
    # each kept block's mean of t lies inside that block
    means = _bmean(t, inv, ids.size)
    assert means.shape == (ids.size,)
    assert np.all((means >= ids) & (means < ids + 1))
