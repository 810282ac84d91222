"""A shorter design's samples taken from a longer one's, and the bound that passes over designs."""

from __future__ import annotations

import numpy as np
import pytest

from bench.planning.evaluation import EVERY_SAMPLE_FS_HZ, Targets, evaluate
from bench.planning.floors import cannot_meet
from bench.planning.information import wander_bound_bias, white_bound_bias, white_bound_k
from bench.planning.noise import UnitNoise
from bench.planning.sampled import SampledTrajectory
from bench.procedures.planned import planned_static, planned_tumble

G = 9.80665


@pytest.mark.parametrize("reps", [1, 2, 3])
def test_the_prefix_is_the_shorter_design_sampled_alone(reps: int) -> None:
    long = SampledTrajectory.sample(planned_tumble(dwell_s=3.0, repeats=4), EVERY_SAMPLE_FS_HZ)
    short = planned_tumble(dwell_s=3.0, repeats=reps)
    got = long.prefix(short)
    alone = SampledTrajectory.sample(short, EVERY_SAMPLE_FS_HZ)
    assert len(got.t_s) == len(alone.t_s) < len(long.t_s)
    for a, b in ((got.t_s, alone.t_s), (got.angles_deg, alone.angles_deg), (got.f_m_s2, alone.f_m_s2)):
        np.testing.assert_array_equal(a, b)
    # the end's finite differences are the short record's own (the long one's move begins there)
    np.testing.assert_array_equal(got.nuisance, alone.nuisance)
    assert not np.array_equal(long.nuisance[len(alone.t_s) - 1], alone.nuisance[-1])
    np.testing.assert_array_equal(got.step_ends, alone.step_ends)


def test_a_design_that_does_not_begin_the_trajectory_is_refused() -> None:
    long = SampledTrajectory.sample(planned_tumble(dwell_s=3.0, repeats=2), EVERY_SAMPLE_FS_HZ)
    assert not long.begins(planned_tumble(dwell_s=5.0, repeats=1))
    with pytest.raises(ValueError, match="do not begin"):
        long.prefix(planned_static(dwell_s=5.0, repeats=1))


@pytest.mark.parametrize("dwell_s, reps", [(2.0, 1), (10.0, 2), (30.0, 1)])
def test_no_every_sample_prediction_is_below_the_bound_that_skips_designs(dwell_s: float, reps: int) -> None:
    noise = UnitNoise.from_ug(250, 40, 200)
    proc = planned_tumble(dwell_s=dwell_s, repeats=reps)
    e = evaluate(proc, noise, fit="every-sample")
    span_s = len(SampledTrajectory.sample(proc, EVERY_SAMPLE_FS_HZ).t_s) / EVERY_SAMPLE_FS_HZ
    k = white_bound_k(noise.white_m_s2_rt_hz, span_s, G)
    # the bias: the white bound, or the wander's over the 1-s blocks of slow noise, the larger
    b = max(
        white_bound_bias(noise.white_m_s2_rt_hz, span_s),
        wander_bound_bias(noise.wander_m_s2, noise.wander_tau_s, span_s + 1.0),
    )
    assert min(e.predicted.scale, e.predicted.misalignment) >= k and e.predicted.bias >= b
    for group, bound in (("scale", k), ("misalignment_rad", k), ("bias_m_s2", b)):
        assert cannot_meet(Targets(**{group: 2 * bound * 0.99}), noise, span_s, G)
        assert not cannot_meet(Targets(**{group: 2 * bound * 1.01}), noise, span_s, G)
