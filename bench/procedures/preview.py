"""Dry run of a procedure: duration, poses and limit checks, without hardware.

As bluesky's ``summarize_plan`` / ``check_limits``: the same step tuple the sequencer
executes is walked here against a table model (:class:`TableLimits`).

Move time of one axis over a distance ``d`` with rate limit ``v`` and acceleration limit
``a`` (trapezoidal profile, triangular when ``d < v²/a``)::

    t = 2·sqrt(d/a)          if d < v²/a
    t = d/v + v/a            otherwise

All axes move together, so a move takes the slowest axis's time plus the settling allowance.
A rotation or an oscillation ends with the table stopping from its rate (an oscillation's
peak rate, which a whole number of periods ends at) at the acceleration limit, ``|ω|/a``.

A dwell not chosen yet (a procedure that records a noise window first) is assumed to be the
longest the noise window can choose (:func:`bench.dwell_policy.longest_noise_window_dwell_s`),
which is also the usual choice: the estimate does not overshoot because of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bench.dwell_policy import longest_noise_window_dwell_s
from bench.procedures.steps import Dwell, MoveTo, NoiseWindow, Oscillate, Procedure, Rotate
from bench.records import WindowKind

FALLBACK_DWELL_S = 60.0
"""Dwell assumed for a static window whose dwell is not chosen yet when the procedure records
no noise window to choose it from (s)."""
DEFAULT_SAMPLE_RATE_HZ = 1000.0
"""DAQ rate (Hz) assumed for the noise window's longest dwell when the caller names none (the
simulated DAQ's default; the bound is 16.384 s for a 60 s window at 250 Hz to 1 kHz alike)."""


@dataclass(frozen=True)
class TableLimits:
    """What the table can do, per axis (outermost first).

    :param pos_lo_deg: lowest angle (deg); ignored for continuous axes.
    :param pos_hi_deg: highest angle (deg); ignored for continuous axes.
    :param max_rate_deg_s: rate limit (deg/s).
    :param max_acc_deg_s2: acceleration limit (deg/s²).
    :param continuous: the axis has a slip ring and may turn without end.
    :param settle_s: the table's ring-down after it reports in position (s): a move's settling
        allowance (``MoveTo.settle_s``) may not be shorter; 0: not stated.
    """

    pos_lo_deg: tuple[float, ...]
    pos_hi_deg: tuple[float, ...]
    max_rate_deg_s: tuple[float, ...]
    max_acc_deg_s2: tuple[float, ...]
    continuous: tuple[bool, ...]
    settle_s: float = 0.0

    @property
    def n_axes(self) -> int:
        """Number of axes."""
        return len(self.max_rate_deg_s)


DEFAULT_TABLE_LIMITS = TableLimits(
    pos_lo_deg=(-180.0, -180.0, -180.0),
    pos_hi_deg=(180.0, 180.0, 180.0),
    max_rate_deg_s=(300.0, 200.0, 300.0),
    max_acc_deg_s2=(200.0, 200.0, 200.0),
    continuous=(True, False, True),
)
"""A three-axis table with slip rings on the outer and inner axes, no settling stated: the limits
of a bench whose file has no ``[table.limits]`` (docs/bench-config.md)."""


@dataclass(frozen=True)
class PreviewWindow:
    """One window of the preview: label, kind, start and duration on the run's clock (s)."""

    index: int
    label: str
    kind: WindowKind
    start_s: float
    duration_s: float
    pose_deg: tuple[float, ...]


@dataclass(frozen=True)
class Preview:
    """Result of :func:`preview`.

    :param duration_s: expected duration of the whole procedure (s).
    :param poses_deg: every commanded pose (deg), in order.
    :param windows: the windows the run will record.
    :param problems: limit violations, one sentence each naming the step; empty when runnable.
    :param assumptions: what the estimate assumed (e.g. a provisional dwell).
    """

    duration_s: float
    poses_deg: tuple[tuple[float, ...], ...]
    windows: tuple[PreviewWindow, ...]
    problems: tuple[str, ...]
    assumptions: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """No limit is violated."""
        return not self.problems


def move_time_s(distance_deg: float, max_rate_deg_s: float, max_acc_deg_s2: float) -> float:
    """Trapezoidal move time (s) over ``distance_deg`` (see the module docstring)."""
    d = abs(distance_deg)
    v, a = max_rate_deg_s, max_acc_deg_s2
    if d < v * v / a:
        return 2.0 * math.sqrt(d / a)
    return d / v + v / a


def _axis_distance(frm: float, to: float, continuous: bool) -> float:
    if continuous:
        return abs((to - frm + 180.0) % 360.0 - 180.0)
    return abs(to - frm)


def preview(
    proc: Procedure,
    limits: TableLimits = DEFAULT_TABLE_LIMITS,
    provisional_dwell_s: float | None = None,
    start_deg: tuple[float, ...] | None = None,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    check_plan: bool = True,
) -> Preview:
    """Walk ``proc`` against ``limits``: duration, poses, windows and limit problems.

    :param proc: the procedure.
    :param limits: the table's limits.
    :param provisional_dwell_s: dwell assumed for ``Dwell(duration_s=None)`` (s); ``None``: the
        longest the procedure's noise window can choose at ``sample_rate_hz``
        (:data:`FALLBACK_DWELL_S` without a noise window).
    :param start_deg: table angles before the run (deg); zeros when ``None``.
    :param sample_rate_hz: the DAQ's rate (Hz), for the noise window's longest dwell.
    :param check_plan: also ask whether a moving-table plan determines the fit's terms
        (:func:`~bench.procedures.observability.plan_blockers`); ``False`` for a part of a
        procedure (what a resume still runs), which is not a plan of its own.
    """
    why = "assumed"
    if provisional_dwell_s is None:
        provisional_dwell_s, why = provisional_dwell(proc, sample_rate_hz)
    n = limits.n_axes
    problems: list[str] = []
    assumptions: list[str] = []
    if proc.n_axes != n:
        problems.append(f"{proc.name} needs a {proc.n_axes}-axis table, the table has {n} axes")
    pos = list(start_deg) if start_deg is not None else [0.0] * n
    t = 0.0
    poses: list[tuple[float, ...]] = []
    windows: list[PreviewWindow] = []

    def check_axis(i: int, axis: int, what: str) -> bool:
        if not 1 <= axis <= n:
            problems.append(f"step {i} ({what}): axis {axis} does not exist (table has {n} axes)")
            return False
        return True

    for i, step in enumerate(proc.steps):
        if isinstance(step, MoveTo):
            if len(step.angles_deg) != n:
                problems.append(f"step {i} (MoveTo {step.label}): {len(step.angles_deg)} angles for {n} axes")
                continue
            for ax, ang in enumerate(step.angles_deg):
                if not limits.continuous[ax] and not limits.pos_lo_deg[ax] <= ang <= limits.pos_hi_deg[ax]:
                    problems.append(
                        f"step {i} (MoveTo {step.label}): axis {ax + 1} angle {ang:g} deg outside "
                        f"[{limits.pos_lo_deg[ax]:g}, {limits.pos_hi_deg[ax]:g}] deg"
                    )
            t += max(
                move_time_s(
                    _axis_distance(pos[ax], step.angles_deg[ax], limits.continuous[ax]),
                    limits.max_rate_deg_s[ax],
                    limits.max_acc_deg_s2[ax],
                )
                for ax in range(n)
            )
            if step.settle_s < limits.settle_s:
                problems.append(
                    f"step {i} (MoveTo {step.label}): settling {step.settle_s:g} s is shorter than "
                    f"the table's {limits.settle_s:g} s"
                )
            t += step.settle_s
            pos = list(step.angles_deg)
            poses.append(tuple(pos))
        elif isinstance(step, NoiseWindow | Dwell):
            dur = step.duration_s
            if dur is None:
                dur = provisional_dwell_s
                msg = f"dwell not yet chosen: {provisional_dwell_s:g} s {why} per static window"
                if msg not in assumptions:
                    assumptions.append(msg)
            windows.append(PreviewWindow(len(windows), step.label, step.kind, t, dur, tuple(pos)))
            t += dur
        elif isinstance(step, Rotate):
            if not check_axis(i, step.axis, f"Rotate {step.label}"):
                continue
            ax = step.axis - 1
            if abs(step.rate_deg_s) > limits.max_rate_deg_s[ax]:
                problems.append(
                    f"step {i} (Rotate {step.label}): rate {step.rate_deg_s:g} deg/s exceeds "
                    f"the axis {step.axis} limit {limits.max_rate_deg_s[ax]:g} deg/s"
                )
            turned = step.rate_deg_s * (step.spinup_s + step.duration_s)
            if not limits.continuous[ax] and not (
                limits.pos_lo_deg[ax] <= pos[ax] + turned <= limits.pos_hi_deg[ax]
            ):
                problems.append(
                    f"step {i} (Rotate {step.label}): axis {step.axis} has no slip ring and "
                    f"would turn {turned:g} deg past its travel"
                )
            windows.append(
                PreviewWindow(
                    len(windows), step.label, step.kind, t + step.spinup_s, step.duration_s, tuple(pos)
                )
            )
            t += step.spinup_s + step.duration_s + abs(step.rate_deg_s) / limits.max_acc_deg_s2[ax]
            pos[ax] = (pos[ax] + turned + 180.0) % 360.0 - 180.0
        elif isinstance(step, Oscillate):
            ok = all(check_axis(i, a, f"Oscillate {step.label}") for a in step.axes)
            if not ok:
                continue
            for a, amp, peak in zip(step.axes, step.amplitudes_deg, step.peak_rate_deg_s(), strict=True):
                ax = a - 1
                if peak > limits.max_rate_deg_s[ax]:
                    problems.append(
                        f"step {i} (Oscillate {step.label}): axis {a} peak rate {peak:.1f} deg/s "
                        f"exceeds {limits.max_rate_deg_s[ax]:g} deg/s"
                    )
                lo, hi = pos[ax] - abs(amp), pos[ax] + abs(amp)
                inside = limits.pos_lo_deg[ax] <= lo and hi <= limits.pos_hi_deg[ax]
                if not limits.continuous[ax] and not inside:
                    problems.append(
                        f"step {i} (Oscillate {step.label}): axis {a} would swing "
                        f"{pos[ax] - abs(amp):g}..{pos[ax] + abs(amp):g} deg, outside "
                        f"[{limits.pos_lo_deg[ax]:g}, {limits.pos_hi_deg[ax]:g}] deg"
                    )
            windows.append(PreviewWindow(len(windows), step.label, step.kind, t, step.duration_s, tuple(pos)))
            stops = (
                p / limits.max_acc_deg_s2[a - 1]
                for a, p in zip(step.axes, step.peak_rate_deg_s(), strict=True)
            )
            t += step.duration_s + max(stops, default=0.0)
    if check_plan and not problems and n == 3 and any(isinstance(s, Rotate | Oscillate) for s in proc.steps):
        from bench.procedures.observability import plan_blockers  # moving-table fit needs (docs/dynamic.md)

        problems += plan_blockers(proc, provisional_dwell_s)
    return Preview(t, tuple(poses), tuple(windows), tuple(problems), tuple(assumptions))


def provisional_dwell(proc: Procedure, sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ) -> tuple[float, str]:
    """The dwell (s) assumed for ``proc`` before the run chooses one, and the words that say why."""
    noise = next((s for s in proc.steps if isinstance(s, NoiseWindow)), None)
    if noise is None:
        return FALLBACK_DWELL_S, "assumed"
    dwell_s = longest_noise_window_dwell_s(noise.duration_s, sample_rate_hz)
    return dwell_s, f"assumed (the longest the {noise.duration_s:g} s noise window can choose)"
