"""How far a run is: the :class:`bench.records.Progress` event the loop emits.

The expected duration is the procedure preview's estimate, never allowed to be reached
early: with n windows in the procedure, the next one to record k, the recording clock at
t (s) and h (s) of it spent held (operator pause, suspension),

    expected_s = h + max(preview_s, (t − h) + (n − k) · preview_s / n),

so a run slower than its preview (re-measured windows) keeps a bar short of its end until
the last window is done, and a held run's bar (working time (t − h) over (expected_s − h),
:attr:`bench.records.Progress.fraction`) stands still while it is held.
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
    held_s: float = 0.0,
) -> Progress:
    """The progress event of a run at step ``step_index`` with the recording clock at ``now_s`` (s).

    :param window_index: the window being recorded, ``None`` between windows.
    :param next_window: the next window to complete (windows before it are done).
    :param preview_s: the preview's duration estimate (s).
    :param held_s: recording-clock time spent held so far (s).
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
        held_s + max(preview_s, now_s - held_s + left_s),
        positions_deg,
        state,
        held_s,
    )
