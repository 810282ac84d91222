"""Whole simulated runs without servers: the bench's three procedures, vectorised.

Each function lays out the table motion as a :class:`~drivers.sim.motion.TableProfile`,
samples it through a :class:`~drivers.sim.physics.SensorPhysics` in one block and returns
a :class:`SimulatedRun` (samples, windows, the truth). Default geometry: the three-axis
table of ``docs/recording-format.md`` (outer vertical, middle horizontal x, inner vertical).

Windows start ``lead_s`` after the move before them ends, so the ``settling`` effect
(ringing for ``duration_s`` after each stop) shows in a window when duration_s > lead_s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from drivers.sim.motion import (
    AxisProfile,
    ConstantRate,
    Hold,
    Oscillation,
    Segment,
    TableProfile,
    TrapezoidMove,
    end_state,
)
from drivers.sim.physics import SensorPhysics
from drivers.sim.sensor_truth import SensorTruth

FloatArray = npt.NDArray[np.float64]

DEFAULT_AXES = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
"""The default three-axis table of ``docs/recording-format.md``, outermost first."""


@dataclass(frozen=True)
class SimulatedRun:
    """A simulated run.

    :param t_s: (n,) sample times (s).
    :param raw: (n, 3) accelerometer outputs (``truth.channel_unit``).
    :param encoder_deg: (n, k) encoder readings, wrapped (deg).
    :param temp_c: (n,) temperature channel (°C).
    :param segments: (start_s, end_s, label) of each window.
    :param truth: the unit that produced it (effects included).
    :param procedure: ``static-12``, ``rate-1axis`` or ``oscillation-2axis``.
    :param sample_rate_hz: the sampling rate (Hz).
    :param axis_vectors: (k, 3) true table axes.
    :param mount: (3, 3) true mount rotation.
    :param g_local_m_s2: true local gravity (m/s²).
    :param profile: the commanded motion (encoder coordinates).
    :param bias_wander_m_s2: (n, 3) slow noise the sensor saw (m/s², see ``SensorSamples``).
    :param encoder_resolution_deg: the step the encoders read in (deg; ``encoder_hold``'s, else
        the physics' ``encoder_resolution_deg``), 0 for exact readings.
    """

    t_s: FloatArray
    raw: FloatArray
    encoder_deg: FloatArray
    temp_c: FloatArray
    segments: tuple[tuple[float, float, str], ...]
    truth: SensorTruth
    procedure: str
    sample_rate_hz: float
    axis_vectors: FloatArray
    mount: FloatArray
    g_local_m_s2: float
    profile: TableProfile
    bias_wander_m_s2: FloatArray
    encoder_resolution_deg: float = 0.0

    def bias_seen(self) -> FloatArray:
        """(3,) the bias this run's windows saw: truth.bias + K·(mean bias wander over the windows).

        The slow wander's mean over a run cannot be told from the bias by any single run;
        a calibration of this run estimates this value, not ``truth.bias`` alone.
        """
        inside = np.zeros(self.t_s.shape, dtype=bool)
        for a, b, _ in self.segments:
            inside |= (self.t_s >= a) & (self.t_s <= b)
        wander = self.bias_wander_m_s2[inside].mean(axis=0) if inside.any() else np.zeros(3)
        return np.asarray(self.truth.bias + self.truth.K @ wander, dtype=float)


class _Timeline:
    """Builds a table profile axis by axis in lockstep (every step lasts the same on all axes)."""

    def __init__(self, start_rad: Sequence[float] | FloatArray) -> None:
        self.segments: list[list[Segment]] = [[] for _ in start_rad]
        self.angles = [float(a) for a in start_rad]
        self.rates = [0.0 for _ in start_rad]
        self.t_s = 0.0

    def _push(self, axis: int, seg: Segment) -> None:
        self.segments[axis].append(seg)
        self.angles[axis], self.rates[axis] = end_state(seg)

    def _continue(self, axis: int, duration_s: float) -> Segment:
        if self.rates[axis] == 0.0:
            return Hold(self.angles[axis], duration_s)
        return ConstantRate(self.angles[axis], self.rates[axis], 1.0, duration_s, self.rates[axis])

    def hold(self, duration_s: float) -> None:
        """Every axis keeps doing what it does (standing or turning) for ``duration_s``."""
        for i in range(len(self.angles)):
            self._push(i, self._continue(i, duration_s))
        self.t_s += duration_s

    def move_to(self, target_rad: Sequence[float], rate_max_rad_s: float, accel_max_rad_s2: float) -> None:
        """Point-to-point move of every axis; shorter moves wait at their target for the longest."""
        if any(r != 0.0 for r in self.rates):
            raise ValueError("move_to: every axis must be at rest")
        moves = [
            TrapezoidMove(a, float(b), rate_max_rad_s, accel_max_rad_s2)
            for a, b in zip(self.angles, target_rad, strict=True)
        ]
        longest = max(m.duration_s for m in moves)
        for i, move in enumerate(moves):
            self._push(i, move)
            if longest - move.duration_s > 0:
                self._push(i, Hold(move.end_rad, longest - move.duration_s))
        self.t_s += longest

    def set_rate(self, axis: int, rate_rad_s: float, accel_rad_s2: float, duration_s: float) -> float:
        """Ramp ``axis`` to a constant rate and keep it for ``duration_s`` in all; returns the ramp time."""
        seg = ConstantRate(self.angles[axis], rate_rad_s, accel_rad_s2, duration_s, self.rates[axis])
        for i in range(len(self.angles)):
            self._push(i, seg if i == axis else self._continue(i, duration_s))
        self.t_s += duration_s
        return seg.ramp_s

    def profile(self) -> TableProfile:
        return TableProfile(tuple(AxisProfile(tuple(s)) for s in self.segments))


def static12_poses_deg() -> FloatArray:
    """Twelve orientations (outer, middle, inner) in degrees for the default geometry.

    With R = Rz(o)·Rx(m)·Rz(i) the reaction to gravity in the sensor frame is
    g·[sin m·sin i, sin m·cos i, cos m]: the six axis directions ±x, ±y, ±z and six
    diagonals. The outer axis (which a level table's gravity does not see) steps through
    0°, 90°, 180°, −90° so that a base tilt shows as a change between poses.
    """
    middle_inner = [
        (0, 0), (180, 0), (90, 0), (90, 180), (90, 90), (90, -90),
        (45, 45), (135, 135), (45, -135), (135, -45), (90, 45), (90, -135),
    ]  # fmt: skip
    outer = [0, 90, 180, -90]
    return np.array([(outer[j % 4], m, i) for j, (m, i) in enumerate(middle_inner)], dtype=float)


def _run(
    physics: SensorPhysics,
    timeline: _Timeline,
    windows: list[tuple[float, float, str]],
    sample_rate_hz: float,
    procedure: str,
) -> SimulatedRun:
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"sample_rate_hz must be > 0, got {sample_rate_hz!r}")
    profile = timeline.profile()
    t = np.arange(math.floor(timeline.t_s * sample_rate_hz) + 1) / sample_rate_hz
    needs_windows = {"pose_error", "encoder_hold"} & set(physics.truth.effects)
    if needs_windows and physics.windows_s is None:
        physics = physics.with_windows([(a, b) for a, b, _ in windows])
    samples = physics.sample(t, profile)
    return SimulatedRun(
        t_s=t,
        raw=samples.raw,
        encoder_deg=samples.encoder_deg,
        temp_c=samples.temp_c,
        segments=tuple(windows),
        truth=physics.truth,
        procedure=procedure,
        sample_rate_hz=float(sample_rate_hz),
        axis_vectors=physics.axis_vectors,
        mount=physics.mount,
        g_local_m_s2=physics.g_local_m_s2,
        profile=profile,
        bias_wander_m_s2=samples.bias_wander_m_s2,
        encoder_resolution_deg=physics.encoder_step_deg,
    )


def simulate_static(
    poses_deg: FloatArray,
    dwell_s: float,
    physics: SensorPhysics,
    sample_rate_hz: float,
    *,
    move_rate_deg_s: float = 30.0,
    move_accel_deg_s2: float = 60.0,
    lead_s: float = 2.0,
) -> SimulatedRun:
    """Static multi-position run: move, wait ``lead_s``, record a ``dwell_s`` window; repeat.

    :param poses_deg: (m, k) encoder angles of each pose (deg); the table starts at the first.
    :returns: windows labelled ``pos01`` … in pose order; the run ends ``lead_s`` after the last.
    """
    poses = np.atleast_2d(np.asarray(poses_deg, dtype=float))
    if poses.shape[1] != physics.axis_vectors.shape[0] or not np.all(np.isfinite(poses)):
        raise ValueError(f"poses_deg must be finite (m, {physics.axis_vectors.shape[0]}), got {poses.shape}")
    if dwell_s <= 0 or lead_s < 0:
        raise ValueError(f"dwell_s must be > 0 and lead_s >= 0, got {dwell_s}, {lead_s}")
    tl = _Timeline(np.deg2rad(poses[0]))
    windows: list[tuple[float, float, str]] = []
    for j, pose in enumerate(poses):
        if j:
            tl.move_to(np.deg2rad(pose), math.radians(move_rate_deg_s), math.radians(move_accel_deg_s2))
        tl.hold(lead_s)
        windows.append((tl.t_s, tl.t_s + dwell_s, f"pos{j + 1:02d}"))
        tl.hold(dwell_s)
    tl.hold(max(lead_s, 2.0 / sample_rate_hz))
    return _run(physics, tl, windows, sample_rate_hz, "static-12")


def simulate_rate_steps(
    physics: SensorPhysics,
    sample_rate_hz: float,
    *,
    rates_deg_s: Sequence[float] = (0.0, 60.0, 120.0, 180.0, 200.0, -200.0, -120.0),
    poses_deg: Sequence[tuple[float, float]] = ((90.0, 0.0), (0.0, 0.0), (90.0, 90.0)),
    dwell_s: float = 9.0,
    accel_deg_s2: float = 100.0,
    lead_s: float = 3.0,
    move_rate_deg_s: float = 30.0,
    move_accel_deg_s2: float = 60.0,
) -> SimulatedRun:
    """Rate-table run (``rate-1axis``): the outer axis turns at constant rates, at several poses.

    At each (middle, inner) pose the outer axis steps through ``rates_deg_s`` (ramps at
    ``accel_deg_s2``), each held ``lead_s`` + a ``dwell_s`` window, then stops. Windows
    are labelled ``m{middle}_i{inner}_r{rate:+}``.
    """
    if physics.axis_vectors.shape[0] != 3:
        raise ValueError("simulate_rate_steps needs a three-axis table (outer, middle, inner)")
    if any(abs(r) > 200.0 for r in rates_deg_s):
        raise ValueError(f"rates_deg_s must stay within ±200 °/s, got {list(rates_deg_s)}")
    first = poses_deg[0]
    tl = _Timeline([0.0, math.radians(first[0]), math.radians(first[1])])
    windows: list[tuple[float, float, str]] = []
    accel = math.radians(accel_deg_s2)
    for j, (middle, inner) in enumerate(poses_deg):
        if j:
            target = [tl.angles[0], math.radians(middle), math.radians(inner)]
            tl.move_to(target, math.radians(move_rate_deg_s), math.radians(move_accel_deg_s2))
        for rate in rates_deg_s:
            ramp = abs(math.radians(rate) - tl.rates[0]) / accel
            start = tl.t_s + ramp + lead_s
            tl.set_rate(0, math.radians(rate), accel, ramp + lead_s + dwell_s)
            windows.append((start, start + dwell_s, f"m{middle:g}_i{inner:g}_r{rate:+g}"))
        ramp = abs(tl.rates[0]) / accel
        tl.set_rate(0, 0.0, accel, ramp + lead_s)
    return _run(physics, tl, windows, sample_rate_hz, "rate-1axis")


def simulate_oscillation(
    physics: SensorPhysics,
    sample_rate_hz: float,
    *,
    duration_s: float = 90.0,
    period_short_s: float = 12.0,
    amplitudes_deg: tuple[float, float] = (360.0, 90.0),
    centre_deg: tuple[float, float, float] = (0.0, 90.0, 55.0),
    lead_s: float = 10.0,
    move_rate_deg_s: float = 30.0,
    move_accel_deg_s2: float = 60.0,
) -> SimulatedRun:
    """Two-axis quasi-harmonic oscillation (``oscillation-2axis``), after docs/methods.md §2.

    The inner axis oscillates with amplitude ``amplitudes_deg[0]`` and period T1, the middle
    axis with ``amplitudes_deg[1]`` and T2 = ``period_short_s``; 2·T1 = 5·T2. Each starts
    at a turning point, θ = c + A·cos(2π·(t − t0)/T), so rates are continuous; the inner
    starts T1/24 (15° of its phase) after the middle. With these phases and the centres
    (middle 90°, inner 55°) gravity reaches beyond ±0.9 g on every sensor axis. The
    window ``oscillation`` spans ``duration_s`` (a whole number of T1) with both axes
    moving; a static window of ``lead_s`` at the centre pose precedes it. Afterwards the
    middle axis finishes its half period and both end at rest.
    """
    if physics.axis_vectors.shape[0] != 3:
        raise ValueError("simulate_oscillation needs a three-axis table (outer, middle, inner)")
    if duration_s <= 0 or period_short_s <= 0:
        raise ValueError(f"duration_s and period_short_s must be > 0, got {duration_s}, {period_short_s}")
    t1, t2 = 2.5 * period_short_s, period_short_s
    cycles = duration_s / t1
    if abs(cycles - round(cycles)) > 1e-9 * max(1.0, cycles):
        raise ValueError(f"duration_s = {duration_s} must be a whole number of long periods T1 = {t1} s")
    a1, a2 = (math.radians(a) for a in amplitudes_deg)
    c = [math.radians(x) for x in centre_deg]
    tl = _Timeline(c)
    windows: list[tuple[float, float, str]] = []
    tl.hold(1.0)
    windows.append((tl.t_s, tl.t_s + lead_s, "static"))
    tl.hold(lead_s + 1.0)
    tl.move_to([c[0], c[1] + a2, c[2] + a1], math.radians(move_rate_deg_s), math.radians(move_accel_deg_s2))
    tl.hold(1.0)
    lag = t1 / 24.0
    middle_s = math.ceil((lag + duration_s) / (0.5 * t2) - 1e-9) * 0.5 * t2  # ends at a turning point
    start = tl.t_s + lag
    half_pi = 0.5 * math.pi
    tl._push(0, Hold(tl.angles[0], middle_s))
    tl._push(1, Oscillation(c[1], a2, t2, middle_s, phase_rad=half_pi))
    tl._push(2, Hold(tl.angles[2], lag))
    tl._push(2, Oscillation(c[2], a1, t1, duration_s, phase_rad=half_pi))
    tl._push(2, Hold(tl.angles[2], middle_s - lag - duration_s))
    tl.t_s += middle_s
    windows.append((start, start + duration_s, "oscillation"))
    tl.rates = [0.0, 0.0, 0.0]
    tl.hold(1.0)
    return _run(physics, tl, windows, sample_rate_hz, "oscillation-2axis")
