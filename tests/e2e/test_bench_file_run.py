"""A bench described by its own file: the simulation is built to the file's geometry and g,
the recording and the run carry them, the certificate names the file, and the fit recovers
the simulated unit (it would not if the belief and the physics differed: a 90° mount or a
0.12 % different g would show in K far outside its sigma)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.bench_config import SIM_BENCH_FILE, load_bench_config
from bench.recording.reader import read_recording
from drivers.sim.physics import SensorTruth
from station.certificates.certificate import bench_configuration
from station.execution.devices import bench_config_for, open_devices
from station.execution.session import start_run
from tests.e2e.helpers import SIM_SPEED, settings_for, z_scores

MOUNT = "[[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]"  # the sensor turned 90° about z
G = 9.80321


def bench_file(tmp_path: Path) -> Path:
    text = SIM_BENCH_FILE.read_text(encoding="utf-8")
    for old, new in [
        ('name = "simulated bench"', 'name = "turned mount"'),
        ("version = 1", "version = 7"),
        ("mount_rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]", f"mount_rotation = {MOUNT}"),
        ("g_local_m_s2 = 9.81535", f"g_local_m_s2 = {G}"),
        ('name = "middle"', 'name = "tilt"'),
    ]:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "turned.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_the_simulated_bench_is_built_to_the_file(tmp_path: Path) -> None:
    # in this process (sim_process off), so that the simulation's physics can be inspected
    settings = settings_for(tmp_path).model_copy(
        update={"bench_file": bench_file(tmp_path), "sim_process": False}
    )
    config = bench_config_for(settings, sim=True)
    with open_devices(settings, True, SIM_SPEED, 3, config=config) as devices:
        assert devices.sim is not None
        assert np.array_equal(devices.sim.physics.mount, np.array(config.mount_rotation))
        assert devices.sim.physics.g_local_m_s2 == G == devices.sim.g_local_m_s2
        assert devices.table.n_axes == 3


def test_the_simulated_table_has_the_file_s_limits(tmp_path: Path) -> None:
    """The file's rates, accelerations and travel reach the simulated controller: the driver
    reads them back over the table protocol (``:LIMIT:ABSOLUTE?``)."""
    limits = """[table.limits]
max_rate_deg_s = [120.0, 45.0, 90.0]
max_acc_deg_s2 = [15.0, 30.0, 60.0]
continuous = [true, false, true]
travel_deg = [[-180, 180], [-100, 110], [-180, 180]]
"""
    path = tmp_path / "slow.toml"
    path.write_text(SIM_BENCH_FILE.read_text(encoding="utf-8").replace("[gravity]", limits + "[gravity]"))
    settings = settings_for(tmp_path).model_copy(update={"bench_file": path, "sim_process": False})
    with open_devices(settings, True, SIM_SPEED, 3) as devices:
        read = [devices.table.limits(a) for a in (1, 2, 3)]
    assert [(x.rate_deg_s, x.acc_deg_s2) for x in read] == [(120.0, 15.0), (45.0, 30.0), (90.0, 60.0)]
    assert [(x.pos_lo_deg, x.pos_hi_deg) for x in read] == [(-180.0, 180.0), (-100.0, 110.0), (-180.0, 180.0)]


def test_a_real_table_without_a_bench_file_is_refused(tmp_path: Path) -> None:
    settings = settings_for(tmp_path).model_copy(update={"table_url": "socket://10.0.0.5:4001"})
    with pytest.raises(ValueError, match="CALBENCH_BENCH_FILE or --bench-file"):
        bench_config_for(settings, sim=False)


@pytest.mark.slow
def test_a_run_on_a_bench_file_records_its_geometry_and_identity(tmp_path: Path) -> None:
    path = bench_file(tmp_path)
    settings = settings_for(tmp_path).model_copy(update={"bench_file": path})
    record = start_run(
        settings, "static-12", "SN-BENCHFILE", sim=True, sim_speed=SIM_SPEED, seed=4, dwell_s=5.0, limits=None
    )
    assert record.outcome is None and record.state.value == "completed", record.error  # no limits given
    rec = read_recording(record.start.recording_path)
    config = load_bench_config(path)
    assert rec.sidecar.g_local_m_s2 == G and rec.sidecar.table == config.table_geometry()
    assert rec.sidecar.table.axes[1].name == "tilt"  # type: ignore[union-attr]
    identity = record.start.parameters["bench_config"]
    assert identity == config.identity() and identity["version"] == 7  # type: ignore[index]
    line = bench_configuration(identity)
    assert "'turned mount' version 7" in line and config.sha256[:12] in line and f"local g {G}" in line
    # The belief matches the physics: the fit recovers the simulated unit within its sigmas.
    z = z_scores(record.calibration.fitted_model(), SensorTruth.typical("V", 4))
    assert np.max(np.abs(z)) < 5.0, z.round(1)
