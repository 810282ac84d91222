"""ModbusDaq against the simulated DAQ over Modbus TCP on loopback: the stream, the map, the physics.

:func:`sim_daq` (clock, physics, engine, server, driver) is shared with the fault tests.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import pytest
from pymodbus.client import ModbusTcpClient

from drivers import daq_registers as reg
from drivers.base import SampleBlock
from drivers.errors import DeviceError, DeviceTimeout, DriverError
from drivers.modbus_daq import ModbusDaq
from drivers.sim.clock import SimClock
from drivers.sim.daq_engine import DaqEngine
from drivers.sim.modbus_server import DaqServer
from drivers.sim.motion import TableKinematics
from drivers.sim.physics import NoiseSpec, SensorPhysics, SensorTruth

G_LOCAL_M_S2 = 9.81535
AXES = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
TRUTH = SensorTruth(
    bias=np.array([1.50, 1.49, 1.51]),
    K=np.array([[0.0178, 2e-5, -1e-5], [1e-5, 0.0176, 3e-5], [-2e-5, 1e-5, 0.0177]]),
    channel_unit="V",
    noise=NoiseSpec(white_m_s2_rt_hz=2.5e-3),
)


def static_kinematics(angles_deg: tuple[float, float, float]):  # type: ignore[no-untyped-def]
    """The table held still at ``angles_deg``."""
    a = np.deg2rad(np.asarray(angles_deg, dtype=float))

    def kinematics(t_s: np.ndarray) -> TableKinematics:
        n = t_s.shape[0]
        zeros = np.zeros((n, 3))
        return TableKinematics(t_s=t_s, angles_rad=np.tile(a, (n, 1)), rates_rad_s=zeros, accels_rad_s2=zeros)

    return kinematics


@dataclass
class Rig:
    clock: SimClock
    engine: DaqEngine
    server: DaqServer
    daq: ModbusDaq


@contextmanager
def sim_daq(
    *,
    rate_hz: float = 100.0,
    speed: float = 1.0,
    truth: SensorTruth = TRUTH,
    pose_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    full_scale: float = 10.0,
    ring_capacity: int = 8192,
    timeout_s: float = 0.5,
) -> Iterator[Rig]:
    clock = SimClock(speed)
    physics = SensorPhysics(truth, AXES, g_local_m_s2=G_LOCAL_M_S2, seed=3, sample_rate_hz=rate_hz)
    engine = DaqEngine(
        clock,
        physics,
        static_kinematics(pose_deg),
        sample_rate_hz=rate_hz,
        ring_capacity=ring_capacity,
        channel_unit=truth.channel_unit,
        full_scale=full_scale,
    )
    server = DaqServer(engine)
    try:
        daq = ModbusDaq(server.url, timeout_s=timeout_s, retries=0)
        try:
            yield Rig(clock, engine, server, daq)
        finally:
            daq.close()
    finally:
        server.close()


def read_all(daq: ModbusDaq, until_seq: int) -> list[SampleBlock]:
    """Blocks up to sequence ``until_seq`` (exclusive); fails on any gap."""
    blocks: list[SampleBlock] = []
    while not blocks or blocks[-1].first_seq + blocks[-1].n < until_seq:
        blocks.append(daq.read_block(100_000, timeout_s=2.0))
    return blocks


def assert_contiguous(blocks: list[SampleBlock], rate_hz: float) -> None:
    seq = 0
    for b in blocks:
        assert b.first_seq == seq
        np.testing.assert_allclose(b.t_s, (seq + np.arange(b.n)) / rate_hz, rtol=0, atol=1e-12)
        seq += b.n


# -- stream ----------------------------------------------------------------------------------
@pytest.mark.timeout(60)
@pytest.mark.parametrize(("rate_hz", "speed"), [(100.0, 1.0), (1000.0, 1.0), (100.0, 10.0), (1000.0, 10.0)])
def test_static_stream_is_read_without_gaps(rate_hz: float, speed: float) -> None:
    # The ring holds 6.5 s at the fastest stream: a loaded CI machine may read slower than
    # real time here without a gap (sustained speed is measured in benchmarks/bench_daq.py).
    # Contiguity is the claim, not reply latency: a reply may take seconds on a loaded machine
    # (0.5 s was exceeded once under load; the reply timeout is tested in test_modbus_daq_faults).
    with sim_daq(rate_hz=rate_hz, speed=speed, ring_capacity=65535, timeout_s=5.0) as rig:
        daq = rig.daq
        daq.start()
        blocks: list[SampleBlock] = []
        wall_end = time.monotonic() + 0.8
        while time.monotonic() < wall_end:
            blocks.append(daq.read_block(100_000, timeout_s=2.0))
        daq.stop()
        counter = int(daq.status()["sample_counter"])  # type: ignore[call-overload]
        blocks += read_all(daq, counter) if sum(b.n for b in blocks) < counter else []
        assert_contiguous(blocks, rate_hz)
        assert sum(b.n for b in blocks) == counter
        assert counter >= 0.3 * rate_hz * speed  # the stream really ran (0.8 s wall)
        assert all(b.flags == () for b in blocks)


def test_samples_agree_with_the_physics_at_rest_z_up() -> None:
    with sim_daq(rate_hz=200.0, speed=10.0) as rig:
        rig.daq.start()
        blocks = read_all(rig.daq, 2000)
    accel = np.concatenate([b.accel for b in blocks])[:2000]
    expected = TRUTH.bias + TRUTH.K @ np.array([0.0, 0.0, G_LOCAL_M_S2])
    sigma_mean = accel.std(axis=0, ddof=1) / np.sqrt(accel.shape[0])
    assert np.all(np.abs(accel.mean(axis=0) - expected) < 5.0 * sigma_mean + 1e-6)
    table = np.concatenate([b.table_deg for b in blocks if b.table_deg is not None])
    assert np.all(table == 0.0)
    temp = np.concatenate([b.temp_c for b in blocks])
    assert np.all(np.isfinite(temp)) and 0.0 < temp.mean() < 60.0


def test_latched_encoders_and_orientation_free_gravity_check_at_a_tilted_pose() -> None:
    pose = (30.0, -45.0, 190.0)
    with sim_daq(rate_hz=200.0, speed=10.0, pose_deg=pose) as rig:
        rig.daq.start()
        blocks = read_all(rig.daq, 2000)
    table = np.concatenate([b.table_deg for b in blocks if b.table_deg is not None])
    np.testing.assert_allclose(table, np.tile([30.0, -45.0, -170.0], (table.shape[0], 1)), atol=1e-6)
    accel = np.concatenate([b.accel for b in blocks])
    f = np.linalg.solve(TRUTH.K, accel.mean(axis=0) - TRUTH.bias)
    sigma_f = 2.5e-3 * np.sqrt(100.0) / np.sqrt(accel.shape[0])  # white density · √(fs/2) / √n
    assert abs(np.linalg.norm(f) - G_LOCAL_M_S2) < 6 * sigma_f
    assert abs(f[2] - G_LOCAL_M_S2) > 1.0  # z is not up: the pose really changed the reading


def test_read_block_respects_max_samples_and_needs_start() -> None:
    with sim_daq(rate_hz=1000.0, speed=5.0) as rig:
        with pytest.raises(DriverError, match="before start"):
            rig.daq.read_block(10, timeout_s=0.5)
        rig.daq.start()
        time.sleep(0.1)
        first = rig.daq.read_block(5, timeout_s=1.0)
        second = rig.daq.read_block(100_000, timeout_s=1.0)
        assert (first.first_seq, first.n) == (0, 5)
        assert second.first_seq == 5 and second.n > reg.WINDOW_CAPACITY  # several windows in one call
        with pytest.raises(ValueError, match="max_samples"):
            rig.daq.read_block(0, timeout_s=1.0)


def test_stopped_stream_times_out_instead_of_returning_nothing_forever() -> None:
    with sim_daq(rate_hz=100.0, speed=1.0) as rig:
        rig.daq.start()
        rig.daq.stop()
        counter = int(rig.daq.status()["sample_counter"])  # type: ignore[call-overload]
        if counter:
            read_all(rig.daq, counter)
        with pytest.raises(DeviceTimeout, match=r"no new sample within 0\.3 s"):
            rig.daq.read_block(10, timeout_s=0.3)


def test_restart_resets_the_counter() -> None:
    with sim_daq(rate_hz=1000.0, speed=2.0) as rig:
        rig.daq.start()
        read_all(rig.daq, 300)
        rig.daq.start()
        block = rig.daq.read_block(50, timeout_s=1.0)
        assert block.first_seq == 0 and block.t_s[0] == 0.0


# -- the register map as the server answers it ------------------------------------------------
@pytest.fixture
def raw_client() -> Iterator[tuple[ModbusTcpClient, Rig]]:
    with sim_daq(rate_hz=100.0, speed=1.0) as rig:
        client = ModbusTcpClient("127.0.0.1", port=rig.server.port, timeout=1.0, retries=0)
        assert client.connect()
        try:
            yield client, rig
        finally:
            client.close()


def test_identity_type_codes_and_instantaneous_channels(raw_client: tuple[ModbusTcpClient, Rig]) -> None:
    client, rig = raw_client
    assert client.read_holding_registers(reg.HR_MODULE_ID, count=1).registers == [0x6017]
    assert client.read_holding_registers(reg.HR_TYPE_CODE, count=8).registers == [0x0143] * 8
    rig.daq.start()
    time.sleep(0.05)
    raw = client.read_holding_registers(reg.HR_AI_RAW, count=3).registers
    latest = rig.engine.latest().accel
    rng = reg.input_range(0x0143)
    values = [reg.raw_to_value(r, rng) for r in raw]
    np.testing.assert_allclose(values, latest, atol=20.0 / 65535)  # one step; the sample may have moved on
    status = client.read_holding_registers(reg.HR_AI_STATUS, count=16).registers
    assert status == [0] * 16
    temp = reg.regs_to_f32(list(client.read_holding_registers(reg.HR_TEMPERATURE, count=2).registers))
    assert 0.0 < temp < 60.0


@pytest.mark.parametrize(
    ("address", "values", "code"),
    [
        (reg.HR_MODULE_ID, [0x1234], 2),  # read-only
        (50, [1], 2),  # outside the map
        (reg.HR_TYPE_CODE, [0x9999], 3),  # unknown type code
        (reg.HR_ACQ_CONTROL, [5], 3),  # only 0 or 1
        (reg.HR_READ_FROM_SEQ, [0], 3),  # half a 32-bit start sequence
    ],
)
def test_writes_outside_the_map_get_modbus_exceptions(
    raw_client: tuple[ModbusTcpClient, Rig], address: int, values: list[int], code: int
) -> None:
    client, _ = raw_client
    rr = client.write_registers(address, values)
    assert rr.isError() and rr.exception_code == code


def test_reads_outside_the_map_get_exception_02(raw_client: tuple[ModbusTcpClient, Rig]) -> None:
    client, _ = raw_client
    rr = client.read_holding_registers(8, count=4)  # between the AI block and the status block
    assert rr.isError() and rr.exception_code == 2
    rr = client.read_holding_registers(reg.HR_END - 2, count=10)
    assert rr.isError() and rr.exception_code == 2


def test_valid_type_code_write_is_kept(raw_client: tuple[ModbusTcpClient, Rig]) -> None:
    client, _ = raw_client
    assert not client.write_registers(reg.HR_TYPE_CODE + 5, [0x0180]).isError()
    assert client.read_holding_registers(reg.HR_TYPE_CODE + 5, count=1).registers == [0x0180]


def test_another_unit_id_is_refused_when_opening() -> None:
    with sim_daq() as rig:
        with pytest.raises(DeviceError) as info:
            ModbusDaq(rig.server.url, device_id=7, timeout_s=0.5, retries=0)
        assert info.value.code == 4 and "unit 7" in str(info.value) and "HR 210-210" in str(info.value)
