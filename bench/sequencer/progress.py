"""How far a run is: the :class:`bench.records.Progress` event the loop emits, with a remaining
time from measured rates.

The nominal schedule is the procedure's preview (:func:`bench.procedures.preview.preview`)
with the dwell the run actually uses once it is chosen: ``E_j`` (s) the nominal end of window
``j``, ``T`` the nominal end of the procedure. With ``a`` the last window done before this
process started (``E_a = 0`` for a fresh run, working time ``w_a`` then), ``d`` the last window
done since, at working time ``w_d`` (recording clock minus time held), the measured ratio of
actual to nominal time is

    r = (w_d − w_a) / (E_d − E_a)          (r = 1 before the first window is done),

and the remaining working time at working time ``w`` is the remaining steps' nominal duration
scaled by it,

    remaining = max(r·(T − E_{d+1}), w_d + r·(T − E_d) − w),

the floor being the nominal rest after the window in progress (a window that overruns keeps
the estimate from reaching zero early). The ratio absorbs what the preview cannot know (move
and settling times of the real table, re-measured windows), so the estimate converges on the
truth as windows complete; the benchmark ``benchmarks/bench_eta.py`` measures it.
"""

from __future__ import annotations

from bench.procedures.preview import DEFAULT_TABLE_LIMITS, TableLimits, preview
from bench.procedures.steps import Procedure
from bench.records import Progress, RunState

PROVISIONAL_DWELL_S = 60.0
"""Dwell assumed by the schedule until the run has chosen one (the preview's own default)."""


class RemainingTime:
    """Remaining working time of a run from its nominal schedule and its measured pace.

    :param procedure: the procedure being run.
    :param limits: the table's limits (the preview's move times).
    :param first_window: the first window this process records (0 for a fresh run).
    :param start_work_s: working time (recording clock minus time held, s) at that point.
    :param dwell_s: the dwell chosen, ``None`` until known.
    """

    def __init__(
        self,
        procedure: Procedure,
        limits: TableLimits = DEFAULT_TABLE_LIMITS,
        first_window: int = 0,
        start_work_s: float = 0.0,
        dwell_s: float | None = None,
    ) -> None:
        self._procedure, self._limits = procedure, limits
        self.first_window, self.start_work_s = first_window, start_work_s
        self.done_window: int | None = None
        self.done_work_s = start_work_s
        self.set_dwell(dwell_s)

    def set_dwell(self, dwell_s: float | None) -> None:
        """Re-plan the nominal schedule with the dwell the run uses (s)."""
        pv = preview(self._procedure, self._limits, provisional_dwell_s=dwell_s or PROVISIONAL_DWELL_S)
        self.ends_s = tuple(w.start_s + w.duration_s for w in pv.windows)
        self.total_s = pv.duration_s

    def window_done(self, index: int, work_s: float) -> None:
        """Window ``index`` completed at working time ``work_s`` (s)."""
        if index >= self.first_window:
            self.done_window, self.done_work_s = index, work_s

    def _end(self, index: int) -> float:
        if index < 0 or not self.ends_s:
            return 0.0
        return self.ends_s[min(index, len(self.ends_s) - 1)]

    @property
    def ratio(self) -> float:
        """Measured actual / nominal time over the windows this process completed (1 before)."""
        if self.done_window is None:
            return 1.0
        nominal = self._end(self.done_window) - self._end(self.first_window - 1)
        actual = self.done_work_s - self.start_work_s
        return actual / nominal if nominal > 0 and actual > 0 else 1.0

    def remaining_s(self, work_s: float) -> float:
        """Remaining working time (s) at working time ``work_s`` (the module's equation)."""
        r = self.ratio
        last = self.first_window - 1 if self.done_window is None else self.done_window
        anchor_work = self.done_work_s
        projected = anchor_work + r * (self.total_s - self._end(last)) - work_s
        floor = r * (self.total_s - self._end(last + 1)) if last + 1 < len(self.ends_s) else 0.0
        return max(0.0, floor, projected)


def run_progress(
    procedure: Procedure,
    step_index: int,
    window_index: int | None,
    next_window: int,
    now_s: float,
    remaining_s: float,
    positions_deg: tuple[float, ...],
    state: RunState,
    held_s: float = 0.0,
) -> Progress:
    """The progress event of a run at step ``step_index`` with the recording clock at ``now_s`` (s).

    :param window_index: the window being recorded, ``None`` between windows.
    :param next_window: the next window to complete (windows before it are done).
    :param remaining_s: the remaining working time (s), :meth:`RemainingTime.remaining_s`.
    :param held_s: recording-clock time spent held so far (s).
    """
    step = procedure.steps[min(step_index, len(procedure.steps) - 1)]
    return Progress(
        step_index,
        len(procedure.steps),
        getattr(step, "label", ""),
        window_index,
        procedure.n_windows,
        now_s,
        now_s + max(0.0, remaining_s),
        positions_deg,
        state,
        held_s,
    )
