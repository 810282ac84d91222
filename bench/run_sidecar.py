"""The run's own entries in its recording's sidecar, as JSON.

calbench-recording/1 keeps what the format has no column for in the sidecar's free entries;
the bench writes three beside ``segments`` (:class:`bench.run_recorder.RunRecorder`, as the
run goes), so a resumed run can rebuild its record from the files alone:

* ``calbench_run``: the run's own record (run id, procedure parameters, dwell, bench
  configuration);
* ``calbench_windows``: per window its kind, pose, means and the time held by its end, in the
  order of ``segments`` (which hold each window's label and times);
* ``calbench_gaps``: every sample gap (:class:`~bench.records.GapRecord`), in order.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from bench.recording.model import Segment
from bench.records import GapRecord, WindowKind, WindowRecord

WINDOWS_KEY = "calbench_windows"
"""Per window: its record (kind, pose, means) and the time held by its end."""
RUN_KEY = "calbench_run"
"""The run's own record: run id, procedure parameters, dwell, bench configuration."""
GAPS_KEY = "calbench_gaps"
"""Every sample gap, in order."""


def gap_to_json(g: GapRecord) -> dict[str, object]:
    """A :class:`GapRecord` as the JSON object of the sidecar's ``calbench_gaps`` list."""
    return dataclasses.asdict(g)


def gap_from_json(d: dict[str, Any]) -> GapRecord:
    """Inverse of :func:`gap_to_json` (unknown keys ignored).

    :raises KeyError, TypeError, ValueError: a required key is missing or not a number.
    """

    def opt_int(v: int | float | str | None) -> int | None:
        return None if v is None else int(v)

    def opt_float(v: int | float | str | None) -> float | None:
        return None if v is None else float(v)

    return GapRecord(
        first_lost_seq=opt_int(d.get("first_lost_seq")),
        n_lost=opt_int(d.get("n_lost")),
        cause=str(d["cause"]),
        after_row=int(d["after_row"]),
        t_last_s=opt_float(d.get("t_last_s")),
        t_resume_s=float(d["t_resume_s"]),
        window_index=opt_int(d.get("window_index")),
        window_label=str(d.get("window_label", "")),
        action=str(d.get("action", "")),
        daq_epoch=int(d.get("daq_epoch", 0)),
    )


def window_to_json(w: WindowRecord, held_s: float) -> dict[str, object]:
    """A :class:`WindowRecord` as the JSON object of the sidecar's ``calbench_windows`` list,
    with ``held_s``: the recording-clock time the run had spent held by the window's end (s)."""
    d = dataclasses.asdict(w)
    d["kind"] = w.kind.value
    d["held_s"] = held_s
    return d


def window_from_json(d: dict[str, Any], seg: Segment) -> WindowRecord:
    """Inverse of :func:`window_to_json`: label and times from the window's segment ``seg``
    (``held_s`` is read by the caller).

    :raises KeyError, TypeError, ValueError: a required key is missing or not a number.
    """
    return WindowRecord(
        index=int(d["index"]),
        label=seg.label,
        kind=WindowKind(d["kind"]),
        start_s=seg.start_s,
        end_s=seg.end_s,
        n_samples=int(d["n_samples"]),
        pose_deg=tuple(d["pose_deg"]),
        mean_table_deg=tuple(d["mean_table_deg"]),
        temp_c_mean=float(d["temp_c_mean"]),
        step_index=int(d["step_index"]),
        means=dict(d.get("means", {})),
    )
