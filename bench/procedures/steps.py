"""The steps a procedure is made of: plain frozen data that touches no device.

A procedure is a tuple of steps (bluesky's plans-as-messages idea). The sequencer executes
them on a :class:`drivers.base.RotaryTable` and :class:`drivers.base.Daq`; the preview
(:mod:`bench.procedures.preview`) reads the same tuple to give duration, poses and limit
checks without hardware.

Angles are degrees and rates deg/s (the table's edge units); axes are 1-based, 1 = outermost,
as in the recording format. Every step that records a *window* (a segment of the
recording) has a ``label``; :class:`MoveTo` records none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bench.records import WindowKind


def _check_finite(what: str, *values: float) -> None:
    for v in values:
        if not math.isfinite(v):
            raise ValueError(f"{what}: expected finite numbers, got {values!r}")


@dataclass(frozen=True)
class MoveTo:
    """Move every axis to ``angles_deg`` and wait until in position plus the settling time.

    :param angles_deg: target angle per axis (deg), outermost first.
    :param label: name of the pose, e.g. ``"pos03"``.
    :param settle_s: time the table is left to ring down after it reports in position, before
        the next window may start (s, DAQ clock); samples keep being recorded meanwhile.
    """

    angles_deg: tuple[float, ...]
    label: str = ""
    settle_s: float = 2.0

    def __post_init__(self) -> None:
        _check_finite(f"MoveTo {self.label!r} angles_deg", *self.angles_deg, self.settle_s)
        if self.settle_s < 0:
            raise ValueError(f"MoveTo {self.label!r}: settle_s must be >= 0, got {self.settle_s}")


@dataclass(frozen=True)
class NoiseWindow:
    """Hold still and record ``duration_s`` of samples to characterise the unit's noise.

    The dwell policy (:mod:`bench.dwell_policy`) derives the static dwell from this window
    when the unit has no recent Allan characterisation.

    :param duration_s: length of the window (s).
    :param label: segment label.
    """

    duration_s: float
    label: str = "noise"
    kind: WindowKind = WindowKind.NOISE

    def __post_init__(self) -> None:
        _check_finite("NoiseWindow duration_s", self.duration_s)
        if self.duration_s <= 0:
            raise ValueError(f"NoiseWindow duration_s must be > 0, got {self.duration_s}")


@dataclass(frozen=True)
class Dwell:
    """Hold the current pose and record a static window.

    :param label: segment label, e.g. ``"pos03"``.
    :param duration_s: window length (s); ``None`` takes the run's chosen dwell time.
    :param static: the window enters the static fit (``False`` for a reference window that
        is only recorded).
    """

    label: str
    duration_s: float | None = None
    static: bool = True
    kind: WindowKind = WindowKind.STATIC

    def __post_init__(self) -> None:
        if self.duration_s is not None:
            _check_finite(f"Dwell {self.label!r} duration_s", self.duration_s)
            if self.duration_s <= 0:
                raise ValueError(f"Dwell {self.label!r} duration_s must be > 0, got {self.duration_s}")


@dataclass(frozen=True)
class Rotate:
    """Turn one axis at a constant rate and record ``duration_s`` once the rate is reached.

    The window starts after ``spinup_s`` (ramp plus settling of the rate loop) and the axis
    is brought to rest at the end of the step.

    :param axis: 1-based axis number.
    :param rate_deg_s: demanded rate (deg/s), signed by the right-hand rule.
    :param duration_s: recorded window at constant rate (s).
    :param label: segment label.
    :param spinup_s: time allowed to reach the rate before the window starts (s).
    """

    axis: int
    rate_deg_s: float
    duration_s: float
    label: str = ""
    spinup_s: float = 3.0
    kind: WindowKind = WindowKind.RATE

    def __post_init__(self) -> None:
        _check_finite(f"Rotate {self.label!r}", self.rate_deg_s, self.duration_s, self.spinup_s)
        if self.axis < 1:
            raise ValueError(f"Rotate {self.label!r}: axis numbers start at 1, got {self.axis}")
        if self.duration_s <= 0 or self.spinup_s < 0:
            raise ValueError(f"Rotate {self.label!r}: duration_s must be > 0 and spinup_s >= 0")


@dataclass(frozen=True)
class Oscillate:
    """Oscillate several axes sinusoidally about their current angles and record the motion.

    Axis ``axes[i]`` follows ``centre_i + amplitudes_deg[i] · sin(2π t / periods_s[i])``.

    :param axes: 1-based axis numbers.
    :param amplitudes_deg: amplitude per axis (deg).
    :param periods_s: period per axis (s).
    :param duration_s: recorded window (s).
    :param label: segment label.
    """

    axes: tuple[int, ...]
    amplitudes_deg: tuple[float, ...]
    periods_s: tuple[float, ...]
    duration_s: float
    label: str = ""
    kind: WindowKind = WindowKind.OSCILLATION

    def __post_init__(self) -> None:
        if not (len(self.axes) == len(self.amplitudes_deg) == len(self.periods_s)) or not self.axes:
            raise ValueError(
                f"Oscillate {self.label!r}: axes, amplitudes_deg and periods_s must have the same "
                f"non-zero length, got {len(self.axes)}, {len(self.amplitudes_deg)}, {len(self.periods_s)}"
            )
        _check_finite(f"Oscillate {self.label!r}", *self.amplitudes_deg, *self.periods_s, self.duration_s)
        if min(self.axes) < 1:
            raise ValueError(f"Oscillate {self.label!r}: axis numbers start at 1, got {self.axes}")
        if min(self.periods_s) <= 0 or self.duration_s <= 0:
            raise ValueError(f"Oscillate {self.label!r}: periods_s and duration_s must be > 0")

    def peak_rate_deg_s(self) -> tuple[float, ...]:
        """Peak rate of each axis, 2π·A/T (deg/s)."""
        return tuple(2 * math.pi * a / p for a, p in zip(self.amplitudes_deg, self.periods_s, strict=True))


Step = MoveTo | NoiseWindow | Dwell | Rotate | Oscillate
WindowStep = NoiseWindow | Dwell | Rotate | Oscillate


def records_window(step: Step) -> bool:
    """The step records a window (a segment of the recording)."""
    return not isinstance(step, MoveTo)


@dataclass(frozen=True)
class Procedure:
    """A named, parameterised sequence of steps.

    :param name: registry name, e.g. ``"static-12"``.
    :param steps: the steps in order.
    :param parameters: the parameters it was built with (JSON-serialisable, stored with the run).
    :param n_axes: table axes the procedure expects.
    """

    name: str
    steps: tuple[Step, ...]
    parameters: dict[str, object]
    n_axes: int = 3

    def window_steps(self) -> list[tuple[int, WindowStep]]:
        """(step index, step) of every window-recording step, in window order."""
        return [(i, s) for i, s in enumerate(self.steps) if not isinstance(s, MoveTo)]

    @property
    def n_windows(self) -> int:
        """Windows the procedure records."""
        return len(self.window_steps())

    def needs_dwell(self) -> bool:
        """Some static window takes the run's chosen dwell (``Dwell(duration_s=None)``)."""
        return any(isinstance(s, Dwell) and s.duration_s is None for s in self.steps)

    def resume_plan(self, next_window: int) -> tuple[int, int | None]:
        """Where a resumed run restarts to record window ``next_window`` and later.

        :returns: (index of the first window step to execute, index of the :class:`MoveTo`
            to execute first so the table is where that step expects it, or ``None``).
        :raises ValueError: ``next_window`` outside 0..n_windows.
        """
        windows = self.window_steps()
        if not 0 <= next_window <= len(windows):
            raise ValueError(f"{self.name}: cannot resume at window {next_window} of {len(windows)}")
        if next_window == len(windows):
            return len(self.steps), None
        step_index = windows[next_window][0]
        move = next((i for i in range(step_index - 1, -1, -1) if isinstance(self.steps[i], MoveTo)), None)
        return step_index, move
