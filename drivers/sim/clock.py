"""A simulated clock that runs faster than the wall clock.

Simulated time t_sim = speed × (wall time elapsed since the clock was created), so a
ten-minute procedure at ``speed=100`` takes six wall seconds. The simulated table
controller, its server and the simulated DAQ all read one :class:`SimClock`, so they
agree on "now".
"""

from __future__ import annotations

import math
import threading
import time


class SimClock:
    """Simulated seconds since creation, advancing ``speed`` times faster than wall time.

    :param speed: simulated seconds per wall second (> 0, finite).

    Thread-safe: :meth:`now_s` and :meth:`sleep` only read immutable state and the
    monotonic wall clock; the lock guards :meth:`set_speed`.
    """

    def __init__(self, speed: float = 1.0) -> None:
        _check_speed(speed)
        self._lock = threading.Lock()
        self._speed = float(speed)
        self._wall0 = time.monotonic()
        self._sim0 = 0.0

    @property
    def speed(self) -> float:
        """Simulated seconds per wall second."""
        with self._lock:
            return self._speed

    def set_speed(self, speed: float) -> None:
        """Change the speed factor from now on; simulated time stays continuous."""
        _check_speed(speed)
        with self._lock:
            wall = time.monotonic()
            self._sim0 += self._speed * (wall - self._wall0)
            self._wall0 = wall
            self._speed = float(speed)

    def now_s(self) -> float:
        """Simulated seconds since the clock started."""
        with self._lock:
            return self._sim0 + self._speed * (time.monotonic() - self._wall0)

    def wall_s(self, sim_s: float) -> float:
        """Wall seconds that ``sim_s`` simulated seconds take at the current speed."""
        with self._lock:
            return sim_s / self._speed

    def sleep(self, sim_s: float) -> None:
        """Block for ``sim_s`` simulated seconds (``sim_s / speed`` wall seconds).

        :raises ValueError: ``sim_s`` negative or not finite.
        """
        if not math.isfinite(sim_s) or sim_s < 0:
            raise ValueError(f"SimClock.sleep: sim_s must be finite and >= 0, got {sim_s!r}")
        time.sleep(self.wall_s(sim_s))


def _check_speed(speed: float) -> None:
    if not (isinstance(speed, int | float) and math.isfinite(speed) and speed > 0):
        raise ValueError(f"SimClock: speed must be a finite number > 0, got {speed!r}")
