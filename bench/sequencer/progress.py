"""How far a run is: the :class:`bench.records.Progress` event the loop emits, with a remaining
time from measured rates.

The nominal schedule is the procedure's preview (:func:`bench.procedures.preview.preview`)
with the dwell the run actually uses once it is chosen (before: the longest its noise window
can choose at the DAQ's rate, the usual choice): window ``j`` lasts ``D_j`` (s), ends
at ``E_j``, and is preceded by the gap ``G_j = E_j − D_j − E_{j−1}`` (moves, settling,
spin-up, stopping: what the preview cannot know; ``E_{−1} = 0``); ``T`` is the nominal end.
A window lasts what its sample count says, so only the gaps are scaled, each by the measured
ratio of actual to nominal gap time of windows of its kind (static, rate, oscillation: their
gaps differ in nature), shrunk towards the ratio of all kinds pooled while the kind has little
measured time::

    r_pool = (ΣA + c) / (ΣN + c),     r_k = (A_k + c·r_pool) / (N_k + c),

with ``A_k``, ``N_k`` the actual and nominal gap time of the windows of kind ``k`` this process
completed (working time: recording clock minus time held; a resumed run counts the windows
it kept as well, with the time held stored beside each) and ``c = 0.1·ΣG`` (s) the weight of
the prior ratio 1. After window ``d``, done at working time ``w_d``, the remaining working time
at working time ``w`` is

    rest(k) = Σ_{j>k} (D_j + r_{kind j}·G_j) + r_pool·(T − E_last),
    remaining = max(rest(d + 1), w_d + rest(d) − w),

the floor being the rest after the window in progress (a window that overruns keeps the
estimate from reaching zero early). The benchmark ``benchmarks/bench_eta.py`` measures it.
"""

from __future__ import annotations

from collections.abc import Sequence

from bench.procedures.preview import DEFAULT_SAMPLE_RATE_HZ, DEFAULT_TABLE_LIMITS, TableLimits, preview
from bench.procedures.steps import Procedure
from bench.records import Progress
from bench.run_state import RunState


class RemainingTime:
    """Remaining working time of a run from its nominal schedule and its measured pace.

    :param procedure: the procedure being run.
    :param limits: the table's limits (the preview's move times).
    :param first_window: the first window this process records (0 for a fresh run).
    :param start_work_s: working time (recording clock minus time held, s) at that point.
    :param dwell_s: the dwell chosen, ``None`` until known.
    :param sample_rate_hz: the DAQ's rate (Hz): the dwell a noise window can choose.
    """

    PRIOR_FRACTION = 0.1
    """Weight of the prior ratio 1, as a fraction of the run's nominal gap time."""

    def __init__(
        self,
        procedure: Procedure,
        limits: TableLimits = DEFAULT_TABLE_LIMITS,
        first_window: int = 0,
        start_work_s: float = 0.0,
        dwell_s: float | None = None,
        sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    ) -> None:
        self._procedure, self._limits, self._sample_rate_hz = procedure, limits, sample_rate_hz
        self.first_window, self.start_work_s = first_window, start_work_s
        self.done_window: int | None = None
        self.done_work_s = start_work_s
        self._actual: dict[str, float] = {}
        self._nominal: dict[str, float] = {}
        self.set_dwell(dwell_s)

    def set_dwell(self, dwell_s: float | None) -> None:
        """Re-plan the nominal schedule with the dwell the run uses (s); ``None``: not chosen yet."""
        pv = preview(self._procedure, self._limits, dwell_s, sample_rate_hz=self._sample_rate_hz)
        self.ends_s = tuple(w.start_s + w.duration_s for w in pv.windows)
        self.lengths_s = tuple(w.duration_s for w in pv.windows)
        self.gaps_s = tuple(
            max(0.0, w.start_s - (self.ends_s[i - 1] if i else 0.0)) for i, w in enumerate(pv.windows)
        )
        self.kinds = tuple(w.kind.value for w in pv.windows)
        self.total_s = pv.duration_s

    def window_done(self, index: int, work_s: float, recorded_s: float) -> None:
        """Window ``index`` completed at working time ``work_s`` after ``recorded_s`` s of it."""
        if index < self.first_window or index >= len(self.gaps_s):
            return
        previous_s = self.done_work_s if self.done_window is not None else self.start_work_s
        self._measure(index, work_s - recorded_s - previous_s)
        self.done_window, self.done_work_s = index, work_s

    def windows_kept(self, done: Sequence[tuple[int, float, float]]) -> None:
        """The pace of the windows an earlier process completed (a resumed run), so the
        resumed run's remaining time, and the fraction done with it, go on from where they
        were instead of starting over from the nominal pace.

        :param done: per kept window, in order from window 0: its index, the working time at
            its end and the time it recorded (s), as :meth:`window_done` takes them.
        """
        previous_s = 0.0
        for index, work_s, recorded_s in done:
            if index < self.first_window and index < len(self.gaps_s):
                self._measure(index, work_s - recorded_s - previous_s)
            previous_s = work_s

    def _measure(self, index: int, actual_gap_s: float) -> None:
        kind = self.kinds[index]
        self._actual[kind] = self._actual.get(kind, 0.0) + max(0.0, actual_gap_s)
        self._nominal[kind] = self._nominal.get(kind, 0.0) + self.gaps_s[index]

    def _prior_s(self) -> float:
        return self.PRIOR_FRACTION * sum(self.gaps_s)

    @property
    def ratio(self) -> float:
        """Measured actual / nominal gap time over every kind, pulled towards 1 (``r_pool``)."""
        c = self._prior_s()
        actual, nominal = sum(self._actual.values()), sum(self._nominal.values())
        return (actual + c) / (nominal + c) if nominal + c > 0 else 1.0

    def kind_ratio(self, kind: str) -> float:
        """``r_k`` of the module's equation for windows of ``kind`` (a WindowKind value)."""
        c, pool = self._prior_s(), self.ratio
        nominal = self._nominal.get(kind, 0.0)
        return (self._actual.get(kind, 0.0) + c * pool) / (nominal + c) if nominal + c > 0 else pool

    def _rest(self, k: int) -> float:
        ratios = {kind: self.kind_ratio(kind) for kind in set(self.kinds[k + 1 :])}
        rest = sum(
            d + ratios[kind] * g
            for d, g, kind in zip(
                self.lengths_s[k + 1 :], self.gaps_s[k + 1 :], self.kinds[k + 1 :], strict=True
            )
        )
        tail = self.total_s - (self.ends_s[-1] if self.ends_s else 0.0)
        return rest + self.ratio * max(0.0, tail)

    def done_fraction(self, work_s: float) -> float:
        """Fraction of the procedure done at working time ``work_s``: its place on the nominal
        schedule, ``(E_d + s·(E_{d+1} − E_d)) / T`` after window ``d`` (``E_{−1} = 0``; past
        the last window the tail ``T − E_last``), where ``s = min(1, (w − w_d) / (D_{d+1} +
        r_{kind}·G_{d+1}))`` is the share of the next window's stretch (approach and window)
        worked so far at the measured pace. It reflects the windows done, weighted by their
        nominal time: it grows with working time, jumps to ``E_{d+1}/T`` when window ``d + 1``
        completes and never moves back when the pace is re-measured. A resumed run starts at
        its last kept window's ``E_d/T`` (the window in progress at the fault is recorded again)."""
        if self.total_s <= 0:
            return 0.0
        last = self.first_window - 1 if self.done_window is None else self.done_window
        since_s = work_s - self.done_work_s  # done_work_s is start_work_s until a window completes
        begin_s = self.ends_s[last] if 0 <= last < len(self.ends_s) else 0.0
        if last + 1 < len(self.ends_s):
            stretch_s = self.ends_s[last + 1] - begin_s
            pace_s = self.lengths_s[last + 1] + self.kind_ratio(self.kinds[last + 1]) * self.gaps_s[last + 1]
        else:
            stretch_s = max(0.0, self.total_s - begin_s)
            pace_s = self.ratio * stretch_s
        share = 1.0 if pace_s <= 0 else min(1.0, max(0.0, since_s / pace_s))
        return min(1.0, max(0.0, (begin_s + share * stretch_s) / self.total_s))

    def remaining_s(self, work_s: float) -> float:
        """Remaining working time (s) at working time ``work_s`` (the module's equation)."""
        last = self.first_window - 1 if self.done_window is None else self.done_window
        projected = self.done_work_s + self._rest(last) - work_s
        floor = self._rest(last + 1) if last + 1 < len(self.ends_s) else 0.0
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
    done_fraction: float | None = None,
) -> Progress:
    """The progress event of a run at step ``step_index`` with the recording clock at ``now_s`` (s).

    :param window_index: the window being recorded, ``None`` between windows.
    :param next_window: the next window to complete (windows before it are done).
    :param remaining_s: the remaining working time (s), :meth:`RemainingTime.remaining_s`.
    :param held_s: recording-clock time spent held so far (s).
    :param done_fraction: the procedure's fraction done, :meth:`RemainingTime.done_fraction`.
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
        done_fraction,
    )
