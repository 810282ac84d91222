"""The bench file: the shipped simulated bench is the simulation's own geometry, every rule
broken is named with its file and key, JSON reads as TOML does, and the channel map reorders
the DAQ's channels (and their flags) into the sensor's x, y, z."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bench.bench_config import (
    SIM_BENCH_FILE,
    BenchConfigError,
    ChannelMappedDaq,
    apply_to_daq,
    load_bench_config,
)
from drivers.base import SampleBlock
from drivers.sim.bench import DEFAULT_AXES, FULL_SCALE, SimBench

REAL = """
format = "calbench-bench/1"
name = "bench-b"
version = 4
[table]
url = "socket://10.0.0.5:4001"
mount_rotation = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
lever_arm_m = [0.0, 0.004, 0.012]
[[table.axes]]
name = "azimuth"
axis = [0, 0, 1]
[[table.axes]]
name = "tilt"
axis = [0, 1, 0]
[gravity]
g_local_m_s2 = 9.80943
u_m_s2 = 2e-6
source = "absolute gravimeter survey 2023, point B2"
[daq]
url = "modbus-tcp://10.0.0.6:502"
channel_unit = "V"
full_scale = 10.0
channels = { x = 1, y = 2, z = 0 }
"""


def write(tmp_path: Path, text: str, name: str = "bench.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_the_shipped_simulated_bench_is_the_simulation_s_geometry() -> None:
    c = load_bench_config(SIM_BENCH_FILE)
    assert c.simulated and c.daq_url is None
    sim_defaults = SimBench.__init__.__kwdefaults__ or {}  # the simulation's own defaults
    assert [a.axis for a in c.axes] == [tuple(a) for a in DEFAULT_AXES]
    assert c.gravity.g_local_m_s2 == sim_defaults["g_local_m_s2"]
    assert c.lever_arm_m == tuple(sim_defaults["lever_arm_m"])
    assert np.array_equal(c.mount_rotation, np.eye(3))
    assert c.full_scale == FULL_SCALE[c.channel_unit] and c.channel_map == (0, 1, 2)


def test_a_real_bench_file_gives_geometry_gravity_channels_and_identity(tmp_path: Path) -> None:
    path = write(tmp_path, REAL)
    c = load_bench_config(path)
    geo = c.table_geometry()
    assert [a.name for a in geo.axes] == ["azimuth", "tilt"] and geo.axes[1].axis == (0.0, 1.0, 0.0)
    assert geo.lever_arm_m == (0.0, 0.004, 0.012) and geo.mount_rotation[0] == (0.0, -1.0, 0.0)
    assert (c.table_url, c.daq_url, c.channel_map) == (
        "socket://10.0.0.5:4001",
        "modbus-tcp://10.0.0.6:502",
        (1, 2, 0),
    )
    ident = c.identity()
    import hashlib

    assert ident["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert (ident["name"], ident["version"], ident["g_local_u_m_s2"]) == ("bench-b", 4, 2e-6)
    as_json = write(tmp_path, json.dumps(tomllib.loads(REAL)), "bench.json")
    j = load_bench_config(as_json)
    assert (j.axes, j.mount_rotation, j.gravity, j.channel_map) == (
        c.axes,
        c.mount_rotation,
        c.gravity,
        c.channel_map,
    )


@pytest.mark.parametrize(
    ("old", "new", "key", "words"),
    [
        ('format = "calbench-bench/1"', 'format = "calbench-bench/2"', "format", "calbench-bench/1"),
        ("version = 4", "version = 0", "version", "integer >= 1"),
        ('name = "bench-b"', "", "name", "missing"),
        (
            "lever_arm_m = [0.0, 0.004, 0.012]",
            "lever_arm_mm = [0, 0, 12]",
            "table.lever_arm_mm",
            "unknown key",
        ),
        ("axis = [0, 1, 0]", "axis = [0, 1, 0.1]", "table.axes[1].axis", "unit vector"),
        ('name = "tilt"', 'name = "azimuth"', "table.axes", "must differ"),
        (
            "[[0, -1, 0], [1, 0, 0], [0, 0, 1]]",
            "[[0, 1, 0], [1, 0, 0], [0, 0, 1]]",
            "table.mount_rotation",
            "rotation",
        ),
        ("g_local_m_s2 = 9.80943", "g_local_m_s2 = 98.0943", "gravity.g_local_m_s2", "not a local gravity"),
        ("g_local_m_s2 = 9.80943", 'g_local_m_s2 = "9.8"', "gravity.g_local_m_s2", "finite number"),
        ("u_m_s2 = 2e-6", "u_m_s2 = 0", "gravity.u_m_s2", "standard uncertainty"),
        (
            'source = "absolute gravimeter survey 2023, point B2"',
            'source = ""',
            "gravity.source",
            "non-empty",
        ),
        (
            "channels = { x = 1, y = 2, z = 0 }",
            "channels = { x = 1, y = 1, z = 0 }",
            "daq.channels",
            "own channel",
        ),
        (
            "channels = { x = 1, y = 2, z = 0 }",
            "channels = { x = 1, y = 2, z = 5 }",
            "daq.channels.z",
            "0, 1 or 2",
        ),
        ('channel_unit = "V"', 'channel_unit = "mV"', "daq.channel_unit", "one of"),
        ('url = "modbus-tcp://10.0.0.6:502"', 'url = "sim://"', "daq.url", "simulated"),
        ("full_scale = 10.0", "full_scale = -1", "daq.full_scale", "> 0"),
    ],
)
def test_each_rule_broken_is_named_with_file_and_key(
    tmp_path: Path, old: str, new: str, key: str, words: str
) -> None:
    assert old in REAL
    path = write(tmp_path, REAL.replace(old, new, 1))
    with pytest.raises(BenchConfigError) as info:
        load_bench_config(path)
    assert info.value.key == key and str(path) in str(info.value) and words in str(info.value), str(
        info.value
    )


def test_unreadable_and_malformed_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(BenchConfigError, match="cannot read"):
        load_bench_config(tmp_path / "missing.toml")
    with pytest.raises(BenchConfigError, match="not valid TOML"):
        load_bench_config(write(tmp_path, "format = \n"))


class ColumnsDaq:
    """Channel c streams the constant c + 1; channel 1 is over range."""

    sample_rate_hz = 100.0
    channel_unit = "V"
    full_scale = 10.0

    def read_block(self, max_samples: int, timeout_s: float) -> SampleBlock:
        n = 4
        accel = np.tile([1.0, 2.0, 3.0], (n, 1))
        return SampleBlock(7, np.arange(n) / 100.0, accel, np.full(n, np.nan), None, ("over_range:ay",))


def test_the_channel_map_puts_the_sensor_axes_in_order_with_their_flags(tmp_path: Path) -> None:
    c = load_bench_config(write(tmp_path, REAL))  # x on channel 1, y on 2, z on 0
    daq = apply_to_daq(c, ColumnsDaq())  # type: ignore[arg-type]
    assert isinstance(daq, ChannelMappedDaq)
    b = daq.read_block(10, 1.0)
    assert b.accel[0].tolist() == [2.0, 3.0, 1.0] and b.first_seq == 7
    assert b.flags == ("over_range:ax",)  # channel 1 carries the sensor's x
    assert daq.sample_rate_hz == 100.0


def test_a_daq_other_than_the_file_says_is_refused(tmp_path: Path) -> None:
    c = load_bench_config(write(tmp_path, REAL.replace("full_scale = 10.0", "full_scale = 5.0")))
    with pytest.raises(BenchConfigError, match=r"daq.full_scale: the DAQ clips at ±10 V, the file says ±5"):
        apply_to_daq(c, ColumnsDaq())  # type: ignore[arg-type]
    c = load_bench_config(write(tmp_path, REAL.replace('channel_unit = "V"', 'channel_unit = "g"')))
    with pytest.raises(BenchConfigError, match=r"daq\.channel_unit"):
        apply_to_daq(c, ColumnsDaq())  # type: ignore[arg-type]
