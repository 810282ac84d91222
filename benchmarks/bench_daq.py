"""Sustained DAQ stream rate over Modbus TCP on loopback, as a ratio to real time.

For a simulated DAQ at ``rate_hz`` on a clock running ``speed`` times real time, the
stream produces ``rate_hz · speed`` samples per wall second. The reader keeps up when it
reads them all without a :class:`DataGap`; the ratio printed is samples read per wall
second over samples produced per wall second (1.00 = keeps up). The baseline measured in
the same run is one Modbus round trip (FC03, 125 registers): its rate, times the 7.8
samples a full read carries, bounds what any reader of this map can sustain.
"""

from __future__ import annotations

import time

import numpy as np

from drivers import daq_registers as reg
from drivers.errors import DataGap
from drivers.modbus_daq import ModbusDaq
from drivers.sim.clock import SimClock
from drivers.sim.daq_engine import DaqEngine
from drivers.sim.modbus_server import DaqServer
from drivers.sim.motion import TableKinematics
from drivers.sim.physics import NoiseSpec, SensorPhysics, SensorTruth

AXES = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
TRUTH = SensorTruth(bias=np.full(3, 1.5), K=np.eye(3) * 0.0177, noise=NoiseSpec(white_m_s2_rt_hz=2.5e-3))
WALL_S = 2.0


def _at_rest(t_s: np.ndarray) -> TableKinematics:
    z = np.zeros((t_s.shape[0], 3))
    return TableKinematics(t_s=t_s, angles_rad=z, rates_rad_s=z, accels_rad_s2=z)


def _rig(rate_hz: float, speed: float) -> tuple[DaqServer, ModbusDaq]:
    clock = SimClock(speed)
    physics = SensorPhysics(TRUTH, AXES, g_local_m_s2=9.81535, seed=0, sample_rate_hz=rate_hz)
    engine = DaqEngine(clock, physics, _at_rest, sample_rate_hz=rate_hz, ring_capacity=16384)
    server = DaqServer(engine)
    return server, ModbusDaq(server.url, timeout_s=1.0, retries=0)


def round_trips_per_s() -> float:
    """FC03 reads of 125 registers per wall second (the baseline)."""
    server, daq = _rig(100.0, 1.0)
    try:
        client = daq._client  # the same pymodbus client the driver uses
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < 1.0:
            client.read_holding_registers(reg.HR_RECORDS, count=reg.MAX_READ_REGS, device_id=1)
            n += 1
        return n / (time.perf_counter() - t0)
    finally:
        daq.close()
        server.close()


def sustained(rate_hz: float, speed: float) -> tuple[float, int]:
    """(samples read per wall s / samples produced per wall s, gaps seen) over WALL_S."""
    server, daq = _rig(rate_hz, speed)
    try:
        daq.start()
        n, gaps = 0, 0
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < WALL_S:
            try:
                n += daq.read_block(100_000, timeout_s=2.0).n
            except DataGap:
                gaps += 1
        return n / (time.perf_counter() - t0) / (rate_hz * speed), gaps
    finally:
        daq.close()
        server.close()


def main() -> None:
    rt = round_trips_per_s()
    per_read = (reg.MAX_READ_REGS - reg.WINDOW_HEADER_REGS) / reg.RECORD_WORDS
    bound = rt * per_read
    print(f"baseline: {rt:.0f} FC03 round trips/s x {per_read:.1f} samples = {bound:.0f} samples/s bound")
    print(f"{'rate_hz':>8} {'speed':>6} {'demand/s':>9} {'read/demand':>12} {'gaps':>5} {'demand/bound':>13}")
    for rate_hz, speed in [(100.0, 1.0), (1000.0, 1.0), (1000.0, 5.0), (1000.0, 10.0), (1000.0, 20.0)]:
        ratio, gaps = sustained(rate_hz, speed)
        demand = rate_hz * speed
        print(f"{rate_hz:8.0f} {speed:6.0f} {demand:9.0f} {ratio:12.3f} {gaps:5d} {demand / bound:13.2f}")


if __name__ == "__main__":
    main()
