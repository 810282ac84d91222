"""A procedure's sampled trajectory, shared by the designs whose steps begin it.

The planner's every-sample search asks, for one dwell, for designs of 1, …, hi passes; the steps
of ``repeats`` passes are the first steps of ``hi`` passes (``bench.procedures.planned``: the
visit order and the outer angles are indexed by the visit), and the table starts from rest at zero
angles in both, so the sampled angles, specific force and time of the shorter design are the
first samples of the longer one (:func:`~bench.planning.trajectory.angle_trajectory` appends the
steps' samples in order). Only the finite differences of the nuisance response
(:func:`~bench.planning.trajectory.nuisance_response`: ``np.gradient``, one-sided at the ends)
see the end of the record: the last sample's rate and the last two samples' accelerations are
taken again on the prefix's own last :data:`TAIL` samples, so :meth:`SampledTrajectory.prefix`
equals sampling the shorter design alone, sample for sample.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bench.planning.trajectory import angle_trajectory_steps, nuisance_response, specific_force
from bench.procedures.preview import DEFAULT_TABLE_LIMITS, TableLimits
from bench.procedures.steps import Procedure

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

TAIL = 5
"""Samples at the prefix's end on which its last rows' differences are taken again: the last
row's central acceleration needs the rates of the two samples before it, each a central
difference of its neighbours."""


@dataclass(frozen=True)
class SampledTrajectory:
    """A procedure sampled at ``fs_hz`` on the table's limits.

    :param proc: the procedure sampled.
    :param fs_hz: sample rate (Hz).
    :param g_m_s2: gravity the force and the tilt response are taken with (m/s²).
    :param t_s: (n,) sample times (s).
    :param angles_deg: (n, 3) table angles (deg).
    :param f_m_s2: (n, 3) specific force in the sensor frame (m/s²).
    :param nuisance: (n, 3, 5) ∂f/∂(lever arm, tilt) (``trajectory.NUISANCE_NAMES``).
    :param step_ends: (n_steps,) samples recorded once each step is done.
    """

    proc: Procedure
    fs_hz: float
    g_m_s2: float
    t_s: FloatArray
    angles_deg: FloatArray
    f_m_s2: FloatArray
    nuisance: FloatArray
    step_ends: IntArray

    @classmethod
    def sample(
        cls,
        proc: Procedure,
        fs_hz: float,
        limits: TableLimits = DEFAULT_TABLE_LIMITS,
        g_m_s2: float = 9.80665,
    ) -> SampledTrajectory:
        """Sample ``proc`` (:func:`~bench.planning.trajectory.angle_trajectory_steps`).

        :raises ValueError: as ``angle_trajectory``.
        """
        t, ang, ends = angle_trajectory_steps(proc, fs_hz, limits)
        return cls(
            proc,
            fs_hz,
            g_m_s2,
            t,
            ang,
            specific_force(ang, g_m_s2),
            nuisance_response(ang, fs_hz, g_m_s2),
            ends,
        )

    def begins(self, proc: Procedure) -> bool:
        """``proc``'s steps are the first steps of this trajectory's procedure (same axes)."""
        n = len(proc.steps)
        return (
            proc.n_axes == self.proc.n_axes
            and 0 < n <= len(self.proc.steps)
            and (proc.steps == self.proc.steps[:n])
        )

    def prefix(self, proc: Procedure) -> SampledTrajectory:
        """The trajectory of ``proc``, whose steps begin this one's (module docstring).

        :raises ValueError: ``proc`` does not begin this trajectory, or is too short to take
            its end's differences again.
        """
        if not self.begins(proc):
            raise ValueError(f"{proc.name}: its steps do not begin those of {self.proc.name}")
        n = int(self.step_ends[len(proc.steps) - 1])
        if n < TAIL:
            raise ValueError(f"{proc.name}: {n} samples, fewer than the {TAIL} its end needs")
        resp = self.nuisance[:n].copy()
        resp[-2:] = nuisance_response(self.angles_deg[n - TAIL : n], self.fs_hz, self.g_m_s2)[-2:]
        return SampledTrajectory(
            proc,
            self.fs_hz,
            self.g_m_s2,
            self.t_s[:n],
            self.angles_deg[:n],
            self.f_m_s2[:n],
            resp,
            self.step_ends[: len(proc.steps)],
        )
