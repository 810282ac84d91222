"""How far a run is: the :class:`bench.records.Progress` event the loop emits.

The expected duration is the procedure preview's estimate, never allowed to be reached
early: with n windows in the procedure, the next one to record k and the recording clock
at t (s),

    expected_s = max(preview_s, t + (n − k) · preview_s / n),

so a run slower than its preview (re-measured windows, suspensions) keeps a bar short of
its end until the last window is done.
"""

from __future__ import annotations

from bench.procedures.steps import Procedure
from bench.records import Progress, RunState


def run_progress(
    procedure: Procedure,
    step_index: int,
    window_index: int | None,
    next_window: int,
    now_s: float,
    preview_s: float,
    positions_deg: tuple[float, ...],
    state: RunState,
) -> Progress:
    """The progress event of a run at step ``step_index`` with the recording clock at ``now_s`` (s).

    :param window_index: the window being recorded, ``None`` between windows.
    :param next_window: the next window to complete (windows before it are done).
    :param preview_s: the preview's duration estimate (s).
    """
    step = procedure.steps[min(step_index, len(procedure.steps) - 1)]
    n_win = max(1, procedure.n_windows)
    left_s = (n_win - next_window) * preview_s / n_win
    return Progress(
        step_index,
        len(procedure.steps),
        getattr(step, "label", ""),
        window_index,
        procedure.n_windows,
        now_s,
        max(preview_s, now_s + left_s),
        positions_deg,
        state,
    )
