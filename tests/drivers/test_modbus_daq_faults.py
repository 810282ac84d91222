"""Each fault of the simulated DAQ surfaces in ModbusDaq as its typed error, in bounded time,
and no sample is lost without being reported."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.base import SampleBlock
from drivers.errors import DataGap, DeviceError, DeviceTimeout, LinkLost
from drivers.modbus_daq import ModbusDaq
from drivers.sim.physics import NoiseSpec, SensorTruth
from tests.drivers.test_modbus_daq import read_all, sim_daq

pytestmark = pytest.mark.timeout(60)


@pytest.mark.parametrize(("code", "name"), [(2, "illegal data address"), (4, "server device failure")])
def test_modbus_exception_is_a_device_error_naming_code_and_registers(code: int, name: str) -> None:
    with sim_daq(rate_hz=100.0, speed=5.0) as rig:
        rig.daq.start()
        before = read_all(rig.daq, 20)
        rig.server.inject_exception(code, n_requests=1)
        with pytest.raises(DeviceError) as info:
            rig.daq.read_block(1000, timeout_s=1.0)
        assert info.value.code == code
        assert f"exception {code:02d} ({name})" in str(info.value)
        assert "HR 420-421" in str(info.value) and "HR 500-" in str(info.value)
        after = rig.daq.read_block(1000, timeout_s=1.0)  # nothing was consumed by the failed call
        assert after.first_seq == before[-1].first_seq + before[-1].n


def test_transient_busy_is_retried_without_losing_a_sample() -> None:
    with sim_daq(rate_hz=100.0, speed=5.0) as rig:
        rig.daq.start()
        first = rig.daq.read_block(1000, timeout_s=1.0)
        rig.server.inject_exception(6, n_requests=3)
        second = rig.daq.read_block(1000, timeout_s=1.0)
        assert second.first_seq == first.first_seq + first.n


def test_persistent_busy_is_a_device_timeout_at_the_deadline() -> None:
    with sim_daq(rate_hz=100.0, speed=5.0) as rig:
        rig.daq.start()
        rig.server.inject_exception(6, n_requests=None)
        with pytest.raises(DeviceTimeout, match=r"busy \(exception 06\)"):
            rig.daq.read_block(1000, timeout_s=0.3)


def test_dropped_block_is_a_data_gap_naming_the_lost_range_then_the_stream_continues() -> None:
    with sim_daq(rate_hz=200.0, speed=5.0) as rig:
        rig.daq.start()
        blocks = read_all(rig.daq, 50)
        expected = blocks[-1].first_seq + blocks[-1].n
        rig.server.drop_samples(37)
        with pytest.raises(DataGap) as info:
            while True:  # samples before the drop still arrive; then the gap is reported
                b = rig.daq.read_block(1000, timeout_s=1.0)
                assert b.first_seq == expected
                expected += b.n
        assert info.value.expected_seq == expected
        assert info.value.got_seq == expected + 37
        assert "37 samples lost" in str(info.value)
        after = rig.daq.read_block(1000, timeout_s=1.0)
        assert after.first_seq == expected + 37


def test_a_reader_slower_than_the_ring_gets_a_data_gap() -> None:
    with sim_daq(rate_hz=1000.0, speed=2.0, ring_capacity=100) as rig:
        rig.daq.start()
        rig.daq.read_block(10, timeout_s=1.0)
        time.sleep(0.3)  # 600 samples produced, the ring keeps 100
        with pytest.raises(DataGap) as info:
            rig.daq.read_block(10_000, timeout_s=1.0)
        assert info.value.got_seq - info.value.expected_seq >= 400


def test_open_circuit_is_flagged_in_the_block_and_the_status() -> None:
    with sim_daq(rate_hz=100.0, speed=5.0) as rig:
        rig.daq.start()
        assert rig.daq.read_block(1000, timeout_s=1.0).flags == ()
        rig.server.set_open_circuit(2)
        time.sleep(0.05)
        blocks: list[SampleBlock] = []
        while not blocks or blocks[-1].flags == ():
            blocks.append(rig.daq.read_block(1000, timeout_s=1.0))
        flagged = blocks[-1]
        assert flagged.flags == ("open_circuit:az",)
        assert flagged.accel[-1, 2] == 10.0  # pinned at +full scale, as ADAM burnout
        status = rig.daq.status()
        assert status["flags"] == {"ax": [], "ay": [], "az": ["open_circuit"]}


def test_over_range_is_clipped_and_flagged() -> None:
    truth = SensorTruth(
        bias=np.array([0.0, 0.0, 1.5]),
        K=np.diag([0.1, 0.1, 0.1]),
        noise=NoiseSpec(white_m_s2_rt_hz=1e-4),
    )  # z reads 1.5 + 0.98 V: beyond a ±2 V range
    with sim_daq(rate_hz=100.0, speed=5.0, truth=truth, full_scale=2.0) as rig:
        rig.daq.start()
        block = read_all(rig.daq, 10)[-1]
        assert block.flags == ("over_range:az",)
        assert np.all(block.accel[:, 2] == 2.0)
        assert np.all(np.abs(block.accel[:, :2]) < 0.01)
        assert rig.daq.status()["flags"] == {"ax": [], "ay": [], "az": ["over_range"]}


def test_silent_device_is_a_device_timeout_and_the_stream_survives() -> None:
    with sim_daq(rate_hz=100.0, speed=5.0, timeout_s=0.3) as rig:
        rig.daq.start()
        first = rig.daq.read_block(1000, timeout_s=1.0)
        rig.server.set_silent(True)
        with pytest.raises(DeviceTimeout, match=r"no reply to FC23 .* within 0\.3 s"):
            rig.daq.read_block(1000, timeout_s=0.3)
        rig.server.set_silent(False)
        again = rig.daq.read_block(1000, timeout_s=1.0)
        assert again.first_seq == first.first_seq + first.n


def test_server_gone_is_link_lost() -> None:
    with sim_daq(rate_hz=100.0, speed=5.0) as rig:
        rig.daq.start()
        rig.daq.read_block(1000, timeout_s=1.0)
        rig.server.close()
        with pytest.raises(LinkLost, match="link lost"):
            for _ in range(3):  # the first call may still be answered from the socket buffer
                rig.daq.read_block(1000, timeout_s=0.5)


def test_connection_refused_is_link_lost_at_open() -> None:
    with sim_daq() as rig:
        port = rig.server.port
    with pytest.raises(LinkLost, match=f"127.0.0.1:{port}.*refused"):
        ModbusDaq(f"modbus-tcp://127.0.0.1:{port}", timeout_s=0.3, retries=0)


@pytest.mark.parametrize("url", ["tcp://127.0.0.1:502", "modbus-tcp://:502", "modbus-tcp://host:99999"])
def test_bad_url_is_rejected(url: str) -> None:
    with pytest.raises(ValueError, match="DAQ URL"):
        ModbusDaq(url)
