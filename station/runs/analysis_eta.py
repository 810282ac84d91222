"""How long the analysis after the recording will take, from the station's own history.

Once every window is recorded the run is analysed — fit, verdict, diagnosis, uncertainty budget,
certificate — and nothing of that is on the recording clock the recording's remaining time
(:mod:`bench.sequencer.progress`) counts. Its wall time depends on the procedure (its windows,
the terms its fit and diagnosis try) and on the station's machine, so it is predicted from this
bench's own completed runs of the same procedure: run ``i``'s analysis lasted ``a_i`` wall
seconds, from the end of its recording to its stored result (measured by the runner and kept in
its final event, :data:`WALL_KEY`), and the next is expected to take

    A = median_i(a_i)

over the last :data:`HISTORY_RUNS` such runs (the median: one analysis slowed by a loaded
machine does not carry the estimate). The recording's length is not a predictor: on the
simulated bench at ×20 static-12 recordings of 357 to 1403 s (the table's round trips
stretched by the machine's load) were analysed in 9 to 19 s with no trend
(``benchmarks/bench_eta_analysis.py``, docs/benchmarks.md). Without any analysed run there is
no estimate (``None``): the dashboard then says so rather than guess.
"""

from __future__ import annotations

import dataclasses
import statistics
from collections.abc import Sequence

import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import Bench, Run, RunState

HISTORY_RUNS = 10
"""Completed runs of the procedure on the bench whose analysis times make the estimate."""
WALL_KEY = "analysis_wall_s"
"""Final-event key: the analysis's wall time (s), end of recording to stored result."""


@dataclasses.dataclass(frozen=True)
class AnalysisPace:
    """The analysis wall time of one procedure on one bench, from its history.

    :param median_s: median of the ``a_i`` (wall seconds).
    :param n_runs: analysed runs it is the median of.
    """

    median_s: float
    n_runs: int

    def expected_s(self) -> float:
        """``A``: the expected analysis wall time (s)."""
        return self.median_s


def pace_from(history: Sequence[float]) -> AnalysisPace | None:
    """The pace of past analysis wall times (s; those > 0); ``None`` without any."""
    times = [a for a in history if a > 0]
    if not times:
        return None
    return AnalysisPace(float(statistics.median(times)), len(times))


def analysis_entry(wall_s: float) -> dict[str, float]:
    """What a completed run's final event keeps of its analysis (:func:`analysis_pace` reads it)."""
    return {WALL_KEY: round(wall_s, 3)}


def analysis_pace(session: Session, bench_name: str, procedure: str) -> AnalysisPace | None:
    """The pace of the last :data:`HISTORY_RUNS` completed runs of ``procedure`` on the bench
    ``bench_name`` whose final event keeps their analysis."""
    rows = session.scalars(
        sa.select(Run.final_event)
        .join(Bench, Bench.id == Run.bench_id)
        .where(Bench.name == bench_name, Run.procedure == procedure, Run.state == RunState.COMPLETED)
        .order_by(Run.finished_at.desc())
        .limit(5 * HISTORY_RUNS)
    ).all()
    history = [
        float(e[WALL_KEY]) for e in rows if isinstance(e, dict) and isinstance(e.get(WALL_KEY), int | float)
    ]
    return pace_from(history[:HISTORY_RUNS])
