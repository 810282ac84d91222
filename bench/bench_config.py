"""The bench's own configuration file (``calbench-bench/1``, TOML or JSON).

What a bench is, stated once by the laboratory instead of assumed: the rotary table's axes
and their names, the fixture's mount rotation and lever arm, local gravity with its source
and standard uncertainty, the DAQ's channel map, unit and range, and the table and DAQ URLs.
The simulated bench is one such file (``bench/data/benches/sim.toml``, :data:`SIM_BENCH_FILE`).

Every recording of a run takes its table geometry and ``g_local_m_s2`` from here, and the
run stores the file's identity (:meth:`BenchConfig.identity`: name, version, SHA-256 of the
bytes, path), so a certificate names the configuration it was made with.

Format (TOML; a ``.json`` file holds the same keys)::

    format = "calbench-bench/1"
    name = "bench-a"              # the bench
    version = 3                   # integer >= 1, raised on every change of the file
    description = "..."           # optional

    [table]
    url = "socket://10.0.0.5:4001"          # or a serial device; sim:// for the simulated bench
    mount_rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]   # sensor frame -> innermost table frame
    lever_arm_m = [0.0, 0.0, 0.012]                       # sensor point in the innermost frame (m)
    [[table.axes]]                # outermost first, 1 to 3 axes
    name = "outer"
    axis = [0, 0, 1]              # unit vector in the parent frame at zero angles
    [table.limits]                # optional: rates, accelerations, travel, settling per axis
    max_rate_deg_s = [300.0]      # (bench.bench_table_limits; without it: DEFAULT_TABLE_LIMITS)
    max_acc_deg_s2 = [200.0]
    continuous = [true]

    [gravity]
    g_local_m_s2 = 9.81535
    u_m_s2 = 1e-5                 # standard uncertainty (k = 1)
    source = "absolute gravimeter survey 2023, point B2"

    [daq]
    url = "modbus-tcp://10.0.0.6:502"        # sim:// for the simulated bench
    channel_unit = "V"            # V, count, m/s2 or g
    full_scale = 10.0             # the channels clip at +- this (channel unit)
    channels = { x = 0, y = 1, z = 2 }       # DAQ stream channel of each sensor axis

Validation is strict: an unknown key, a missing one, a wrong type, a non-unit axis, a mount
that is not a rotation, g outside 9.76–9.84 m/s², a channel map that is not a permutation
of the stream's three channels, a table limit that is absurd or not finite
(:mod:`bench.bench_table_limits`): :class:`BenchConfigError` naming the file and the key.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.bench_table_limits import parse_table_limits
from bench.procedures.preview import DEFAULT_TABLE_LIMITS, TableLimits
from bench.recording.model import TableAxis, TableGeometry
from drivers.base import Daq, SampleBlock

FORMAT = "calbench-bench/1"
SIM_BENCH_FILE = Path(__file__).parent / "data" / "benches" / "sim.toml"
"""The simulated bench's configuration, shipped with calbench."""
CHANNEL_UNITS = ("V", "count", "m/s2", "g")
G_RANGE_M_S2 = (9.76, 9.84)
"""Local gravity anywhere on the Earth's surface (equator at altitude to the poles)."""
_TOL = 1e-6


class BenchConfigError(ValueError):
    """A bench file broke a rule; the message names the file and the key."""

    def __init__(self, path: str | Path, key: str, message: str) -> None:
        self.path = str(path)
        self.key = key
        super().__init__(f"{path}: {key}: {message}" if key else f"{path}: {message}")


@dataclass(frozen=True)
class GravityConfig:
    """Local gravity at the bench.

    :param g_local_m_s2: the value (m/s²).
    :param u_m_s2: its standard uncertainty (k = 1, m/s²).
    :param source: where the value comes from (survey, model, reference).
    """

    g_local_m_s2: float
    u_m_s2: float
    source: str


@dataclass(frozen=True)
class BenchConfig:
    """One bench, as its file states it (see the module docstring for the keys).

    :param channel_map: DAQ stream channel (0–2) of the sensor's x, y and z outputs.
    :param sha256: SHA-256 of the file's bytes; :param path: where it was read.
    :param limits: the file's ``[table.limits]``; ``None``: the file states none.
    """

    name: str
    version: int
    description: str
    table_url: str
    daq_url: str | None
    axes: tuple[TableAxis, ...]
    mount_rotation: tuple[tuple[float, float, float], ...]
    lever_arm_m: tuple[float, float, float]
    gravity: GravityConfig
    channel_unit: str
    full_scale: float
    channel_map: tuple[int, int, int]
    sha256: str
    path: str
    limits: TableLimits | None = None

    def table_limits(self) -> TableLimits:
        """The limits this bench's table runs with: the file's ``[table.limits]``, else
        :data:`~bench.procedures.preview.DEFAULT_TABLE_LIMITS` (docs/bench-config.md)."""
        return self.limits if self.limits is not None else DEFAULT_TABLE_LIMITS

    @property
    def simulated(self) -> bool:
        """The table URL is ``sim://``: the file describes the simulated bench."""
        return self.table_url.lower().startswith("sim:")

    def table_geometry(self) -> TableGeometry:
        """The recording sidecar's ``table``."""
        return TableGeometry(self.axes, self.mount_rotation, self.lever_arm_m)

    def identity(self) -> dict[str, object]:
        """What a run stores of it (``run.params["bench_config"]``) and a certificate shows."""
        return {
            "name": self.name,
            "version": self.version,
            "sha256": self.sha256,
            "path": self.path,
            "g_local_m_s2": self.gravity.g_local_m_s2,
            "g_local_u_m_s2": self.gravity.u_m_s2,
            "g_local_source": self.gravity.source,
        }


# -- reading --------------------------------------------------------------------------------


def load_bench_config(path: str | Path) -> BenchConfig:
    """Read and validate a bench file (``.json``: JSON, anything else: TOML).

    :raises BenchConfigError: unreadable, not TOML/JSON, or a key breaks a rule (named).
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise BenchConfigError(p, "", f"cannot read the bench file: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")
        doc = json.loads(text) if p.suffix.lower() == ".json" else tomllib.loads(text)
    except UnicodeDecodeError as exc:
        raise BenchConfigError(p, "", f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise BenchConfigError(
            p, "", f"not valid {'JSON' if p.suffix.lower() == '.json' else 'TOML'}: {exc}"
        ) from None
    if not isinstance(doc, dict):
        raise BenchConfigError(p, "", "the top level must be a table of keys")
    return _parse(doc, p, hashlib.sha256(raw).hexdigest())


class _Reader:
    """Typed access to one table of the document, naming ``file: section.key`` on errors."""

    def __init__(self, doc: dict[str, Any], path: Path, section: str, allowed: set[str]) -> None:
        self.doc, self.path, self.section = doc, path, section
        unknown = sorted(set(doc) - allowed)
        if unknown:
            raise BenchConfigError(
                path, self.key(unknown[0]), f"unknown key; expected one of {', '.join(sorted(allowed))}"
            )

    def key(self, name: str) -> str:
        return f"{self.section}.{name}" if self.section else name

    def fail(self, name: str, message: str) -> BenchConfigError:
        return BenchConfigError(self.path, self.key(name), message)

    def get(self, name: str, default: Any = ...) -> Any:
        if name not in self.doc:
            if default is ...:
                raise self.fail(name, "missing")
            return default
        return self.doc[name]

    def text(self, name: str, default: Any = ...) -> str:
        v = self.get(name, default)
        if not isinstance(v, str) or (default is ... and not v.strip()):
            raise self.fail(name, f"must be a non-empty string, got {v!r}")
        return v

    def number(self, name: str, default: Any = ...) -> float:
        return _number(self.get(name, default), self, name)

    def table(self, name: str, allowed: set[str]) -> _Reader:
        v = self.get(name)
        if not isinstance(v, dict):
            raise self.fail(name, f"must be a table, got {type(v).__name__}")
        return _Reader(v, self.path, self.key(name), allowed)


def _number(v: Any, r: _Reader, name: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(float(v)):
        raise r.fail(name, f"must be a finite number, got {v!r}")
    return float(v)


def _vector(v: Any, r: _Reader, name: str) -> tuple[float, float, float]:
    if not isinstance(v, list) or len(v) != 3:
        raise r.fail(name, f"must be a list of 3 numbers, got {v!r}")
    x, y, z = (_number(e, r, f"{name}[{i}]") for i, e in enumerate(v))
    return (x, y, z)


def _parse(doc: dict[str, Any], path: Path, sha256: str) -> BenchConfig:
    top = _Reader(doc, path, "", {"format", "name", "version", "description", "table", "gravity", "daq"})
    fmt = top.get("format")
    if fmt != FORMAT:
        raise top.fail("format", f"must be {FORMAT!r}, got {fmt!r}")
    name = top.text("name")
    version = top.get("version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise top.fail("version", f"must be an integer >= 1, got {version!r}")
    description = top.text("description", "")

    table = top.table("table", {"url", "axes", "mount_rotation", "lever_arm_m", "limits"})
    table_url = table.text("url")
    axes_raw = table.get("axes")
    if not isinstance(axes_raw, list) or not 1 <= len(axes_raw) <= 3:
        raise table.fail("axes", "must list 1 to 3 axes, outermost first")
    axes: list[TableAxis] = []
    for i, a in enumerate(axes_raw):
        if not isinstance(a, dict):
            raise table.fail(f"axes[{i}]", "must be a table with name and axis")
        ar = _Reader(a, path, table.key(f"axes[{i}]"), {"name", "axis"})
        axis = _vector(ar.get("axis"), ar, "axis")
        norm = math.sqrt(sum(c * c for c in axis))
        if abs(norm - 1.0) > _TOL:
            raise ar.fail("axis", f"must be a unit vector, |axis| = {norm:.9g}")
        axes.append(TableAxis(ar.text("name"), axis))
    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        raise table.fail("axes", f"axis names must differ, got {names}")
    m_raw = table.get("mount_rotation", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    if not isinstance(m_raw, list) or len(m_raw) != 3:
        raise table.fail("mount_rotation", "must be 3 rows of 3 numbers")
    mount = tuple(_vector(row, table, f"mount_rotation[{i}]") for i, row in enumerate(m_raw))
    m = np.array(mount)
    if np.max(np.abs(m @ m.T - np.eye(3))) > _TOL or np.linalg.det(m) < 0:
        raise table.fail("mount_rotation", f"must be a rotation (orthonormal, det +1), got {m.tolist()}")
    arm = _vector(table.get("lever_arm_m", [0.0, 0.0, 0.0]), table, "lever_arm_m")
    if max(abs(c) for c in arm) > 1.0:
        raise table.fail("lever_arm_m", f"must be within 1 m of the innermost axis, got {list(arm)} m")
    limits = None
    if "limits" in table.doc:
        limits = parse_table_limits(
            table.doc["limits"],
            len(axes),
            lambda k, m: BenchConfigError(path, table.key(f"limits.{k}" if k else "limits"), m),
        )

    grav = top.table("gravity", {"g_local_m_s2", "u_m_s2", "source"})
    g = grav.number("g_local_m_s2")
    if not G_RANGE_M_S2[0] <= g <= G_RANGE_M_S2[1]:
        raise grav.fail(
            "g_local_m_s2", f"{g} m/s² is not a local gravity on Earth ({G_RANGE_M_S2[0]}–{G_RANGE_M_S2[1]})"
        )
    u_g = grav.number("u_m_s2")
    if not 0.0 < u_g < 0.01:
        raise grav.fail("u_m_s2", f"must be a standard uncertainty in (0, 0.01) m/s², got {u_g}")
    gravity = GravityConfig(g, u_g, grav.text("source"))

    daq = top.table("daq", {"url", "channel_unit", "full_scale", "channels"})
    daq_url = daq.text("url")
    unit = daq.get("channel_unit")
    if unit not in CHANNEL_UNITS:
        raise daq.fail("channel_unit", f"must be one of {', '.join(CHANNEL_UNITS)}, got {unit!r}")
    full_scale = daq.number("full_scale")
    if full_scale <= 0:
        raise daq.fail("full_scale", f"must be > 0, got {full_scale}")
    ch = daq.table("channels", {"x", "y", "z"})
    chans = []
    for axis_name in ("x", "y", "z"):
        c = ch.get(axis_name)
        if isinstance(c, bool) or not isinstance(c, int) or c not in (0, 1, 2):
            raise ch.fail(axis_name, f"must be a stream channel 0, 1 or 2, got {c!r}")
        chans.append(c)
    if sorted(chans) != [0, 1, 2]:
        raise daq.fail(
            "channels",
            f"must give each sensor axis its own channel, got x={chans[0]}, y={chans[1]}, z={chans[2]}",
        )

    simulated = table_url.lower().startswith("sim:")
    if simulated != daq_url.lower().startswith("sim:"):
        raise daq.fail(
            "url",
            f"the simulated table needs the simulated DAQ and the other way round "
            f"(table.url {table_url!r}, daq.url {daq_url!r})",
        )
    if not simulated and not daq_url.lower().startswith("modbus-tcp://"):
        raise daq.fail("url", f"must be modbus-tcp://host:port, got {daq_url!r}")
    return BenchConfig(
        name=name,
        version=version,
        description=description,
        table_url=table_url,
        daq_url=None if simulated else daq_url,
        axes=tuple(axes),
        mount_rotation=mount,
        lever_arm_m=arm,
        gravity=gravity,
        channel_unit=str(unit),
        full_scale=full_scale,
        channel_map=(chans[0], chans[1], chans[2]),
        sha256=sha256,
        path=str(path),
        limits=limits,
    )


# -- applying it ----------------------------------------------------------------------------

_STREAM_NAMES = ("ax", "ay", "az")


class ChannelMappedDaq:
    """A :class:`drivers.base.Daq` whose blocks carry the sensor's x, y, z in that order.

    Column i of each block's ``accel`` is stream channel ``channel_map[i]``; the block's
    channel flags (``over_range:ay``) are renamed the same way. Everything else is the DAQ's.

    :param daq: the DAQ as wired.
    :param channel_map: stream channel (0–2) of the sensor's x, y and z outputs.
    """

    def __init__(self, daq: Daq, channel_map: tuple[int, int, int]) -> None:
        if sorted(channel_map) != [0, 1, 2]:
            raise ValueError(f"channel map must be a permutation of 0, 1, 2, got {channel_map}")
        self.daq = daq
        self.channel_map = channel_map
        self._rename = {_STREAM_NAMES[c]: _STREAM_NAMES[i] for i, c in enumerate(channel_map)}

    def read_block(self, max_samples: int, timeout_s: float) -> SampleBlock:
        """The DAQ's block with its acceleration columns in sensor order."""
        b = self.daq.read_block(max_samples, timeout_s)
        flags = []
        for f in b.flags:
            kind, _, chan = f.partition(":")
            flags.append(f"{kind}:{self._rename.get(chan, chan)}" if chan else f)
        return dataclasses.replace(
            b, accel=np.asarray(b.accel)[:, list(self.channel_map)], flags=tuple(sorted(flags))
        )

    def __getattr__(self, name: str) -> Any:
        return getattr(self.daq, name)


def apply_to_daq(config: BenchConfig, daq: Daq) -> Daq:
    """Check the DAQ against the file and map its channels.

    :raises BenchConfigError: the DAQ's channel unit or full scale differs from the file's.
    """
    if daq.channel_unit != config.channel_unit:
        raise BenchConfigError(
            config.path,
            "daq.channel_unit",
            f"the DAQ streams {daq.channel_unit!r}, the file says {config.channel_unit!r}",
        )
    fs = getattr(daq, "full_scale", None)
    if isinstance(fs, float) and abs(fs - config.full_scale) > 1e-6 * config.full_scale:
        raise BenchConfigError(
            config.path,
            "daq.full_scale",
            f"the DAQ clips at ±{fs:g} {daq.channel_unit}, the file says ±{config.full_scale:g}",
        )
    return daq if config.channel_map == (0, 1, 2) else ChannelMappedDaq(daq, config.channel_map)
