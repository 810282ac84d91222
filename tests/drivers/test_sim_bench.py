"""SimBench end to end: the real table driver moves the simulated table, the real DAQ driver
sees the accelerometer follow as the physics says; plus the factory's URLs."""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import numpy as np
import pytest

from drivers.base import Daq, RotaryTable, SampleBlock
from drivers.errors import LinkLost
from drivers.factory import BenchDevices, open_bench, open_daq, parse_sim_url
from drivers.sim.bench import SimBench
from drivers.sim.physics import NoiseSpec, SensorTruth
from drivers.table import SerialRotaryTable

pytestmark = pytest.mark.timeout(120)

G = 9.81535
TRUTH = SensorTruth(
    bias=np.array([1.50, 1.49, 1.51]),
    K=np.array([[0.0178, 2e-5, -1e-5], [1e-5, 0.0176, 3e-5], [-2e-5, 1e-5, 0.0177]]),
    noise=NoiseSpec(white_m_s2_rt_hz=2.5e-3),
)


def drain(daq: Daq, n_min: int) -> list[SampleBlock]:
    blocks: list[SampleBlock] = []
    while sum(b.n for b in blocks) < n_min:
        blocks.append(daq.read_block(100_000, timeout_s=2.0))
    return blocks


def assert_mean_is(accel: np.ndarray, f_sensor: np.ndarray) -> None:
    """Mean raw output equals bias + K·f within 5 standard errors of the data itself."""
    expected = TRUTH.bias + TRUTH.K @ f_sensor
    sem = accel.std(axis=0, ddof=1) / np.sqrt(accel.shape[0])
    assert np.all(np.abs(accel.mean(axis=0) - expected) < 5 * sem + 1e-6), (accel.mean(axis=0), expected)


@pytest.fixture
def bench() -> Iterator[BenchDevices]:
    devices = open_bench("sim://?speed=10&rate=200&seed=1", truth=TRUTH)
    yield devices
    devices.close()


def test_open_bench_gives_the_real_drivers_on_loopback(bench: BenchDevices) -> None:
    assert isinstance(bench.table, RotaryTable) and isinstance(bench.table, SerialRotaryTable)
    assert isinstance(bench.daq, Daq)
    assert bench.sim is not None
    assert bench.sim.table_url.startswith("socket://127.0.0.1:")
    assert bench.sim.daq_url.startswith("modbus-tcp://127.0.0.1:")
    assert bench.daq.sample_rate_hz == 200.0 and bench.daq.channel_unit == "V"
    assert bench.sim.clock.speed == 10.0
    np.testing.assert_array_equal(bench.sim.geometry.lever_arm_m, [0.0, 0.0, 0.0])


def test_moving_the_table_changes_the_accelerometer_as_the_physics_says(bench: BenchDevices) -> None:
    table, daq = bench.table, bench.daq
    assert isinstance(table, SerialRotaryTable)
    table.prepare()
    daq.start()
    at_rest = drain(daq, 400)
    accel = np.concatenate([b.accel for b in at_rest])
    assert_mean_is(accel, np.array([0.0, 0.0, G]))  # all angles zero: z up

    table.move_to((0.0, 90.0, 0.0), timeout_s=30.0)  # middle axis (x) +90 deg
    during = drain(daq, 1)
    seq = during[-1].first_seq + during[-1].n
    after = drain(daq, 400)
    assert after[0].first_seq == seq  # no gap across the move
    blocks = at_rest + during + after
    for prev, nxt in itertools.pairwise(blocks):
        assert nxt.first_seq == prev.first_seq + prev.n

    table_deg = np.concatenate([b.table_deg for b in blocks if b.table_deg is not None])
    middle = table_deg[:, 1]
    assert middle[0] == pytest.approx(0.0, abs=1e-5) and middle[-1] == pytest.approx(90.0, abs=0.02)
    assert np.all(np.diff(middle) >= -1e-5)  # the DAQ latched the move as it happened
    moving = (middle > 1.0) & (middle < 89.0)
    assert moving.sum() >= 3

    settled = np.concatenate([b.accel for b in after])[-300:]
    # f = Rᵀ [0, 0, g] with R = Rot(x, 90°): the sensor's y axis now points up.
    assert_mean_is(settled, np.array([0.0, G, 0.0]))


def test_closing_the_bench_drops_the_drivers_links() -> None:
    devices = open_bench("sim://?speed=10&rate=100&seed=2", truth=TRUTH)
    try:
        devices.daq.start()
        drain(devices.daq, 5)
        assert devices.sim is not None
        devices.sim.close()
        with pytest.raises(LinkLost):
            for _ in range(3):
                devices.daq.read_block(100, timeout_s=0.5)
    finally:
        devices.close()


def test_simbench_ring_fits_the_controller_history() -> None:
    with SimBench(TRUTH, speed=1.0, sample_rate_hz=1000.0) as sim:
        assert sim.engine.capacity <= 0.8 * sim.controller.history_s * 1000.0
        assert sim.engine.n_axes == 3 and sim.channel_unit == "V"


def test_simbench_rejects_impossible_geometry() -> None:
    with pytest.raises(ValueError, match="axes must be"):
        SimBench(TRUTH, axes=[[0, 0, 1]] * 4)
    with pytest.raises(ValueError, match="lever_arm_m"):
        SimBench(TRUTH, lever_arm_m=(0.0, float("nan"), 0.0))


def test_sim_url_parameters() -> None:
    assert parse_sim_url("sim://?speed=100&rate=1000&seed=1") == {"speed": 100.0, "rate": 1000.0, "seed": 1}
    assert parse_sim_url("sim://") == {}
    with pytest.raises(ValueError, match="unknown parameter 'sped'"):
        parse_sim_url("sim://?sped=2")
    with pytest.raises(ValueError, match="seed='x' is not a int"):
        parse_sim_url("sim://?seed=x")
    with pytest.raises(ValueError, match="2 times"):
        parse_sim_url("sim://?rate=1&rate=2")


def test_factory_rejects_bad_daq_urls_and_combinations() -> None:
    with pytest.raises(ValueError, match="modbus-tcp://"):
        open_daq("http://127.0.0.1:80")
    with pytest.raises(ValueError, match="open_bench"):
        open_daq("sim://")
    with pytest.raises(ValueError, match="use sim:// for both"):
        open_bench("sim://", "modbus-tcp://127.0.0.1:502")
    with pytest.raises(ValueError, match="a DAQ URL"):
        open_bench("socket://127.0.0.1:1")
    with pytest.raises(ValueError, match="speed"):
        open_bench("sim://?speed=-1")
