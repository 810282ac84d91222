"""The pipelines of a window-means diagnosis (static, hand-held, orientation-free): its named
stages in order, one rule each.

Each stage is ``stage(evidence, state, thresholds) -> (state, notes)`` (``pipeline``) over a
``window_state.WindowState``: the screen and fixed noise before the selection
(``screen_stages``), the forward selection (``selection_stages``, through ``selection.select``),
the checks that resume it (``check_stages``, ``referee``), the head to head with a channel's
own excess (``head_to_head_stage``), and the report's refit and tests (``report_stages``). The
report (``bench.diagnosis.diagnose``) is built from the final state.
"""

from __future__ import annotations

from bench.diagnosis.check_stages import out_of_sample_referee, prune_redundant
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.head_to_head_stage import excess_head_to_head
from bench.diagnosis.pipeline import Pipeline
from bench.diagnosis.report_stages import (
    bench_lines,
    refit_sequence,
    settling,
    unexplained_stage,
    within_window,
)
from bench.diagnosis.screen_stages import (
    encoder_quantisation,
    library_search,
    orientation_prior,
    screen_catalogue,
)
from bench.diagnosis.selection_stages import forward_selection
from bench.diagnosis.window_state import WindowState

_SELECT = (forward_selection, prune_redundant, out_of_sample_referee, excess_head_to_head)
_REPORT = (within_window, refit_sequence, bench_lines, settling, unexplained_stage)

STATIC: Pipeline[StaticEvidence, WindowState] = Pipeline(
    "static", (screen_catalogue, encoder_quantisation, library_search, *_SELECT, *_REPORT)
)
"""Windows whose specific force the recording knows (a table's encoders, or hand-held poses
labelled ``nominal_up``: the screen sets the table's effects aside when there is no table)."""

STATIC_NO_LIBRARY: Pipeline[StaticEvidence, WindowState] = Pipeline(
    "static, catalogue only", (screen_catalogue, encoder_quantisation, *_SELECT, *_REPORT)
)
"""As :data:`STATIC` without the term library (``diagnose(use_library=False)``)."""

ORIENTATION_FREE: Pipeline[StaticEvidence, WindowState] = Pipeline(
    "orientation-free",
    (screen_catalogue, orientation_prior, encoder_quantisation, library_search, *_SELECT, *_REPORT),
)
"""Windows whose orientation the recording does not know: only each reading's magnitude."""


def pipeline_for(ev: StaticEvidence, use_library: bool = True) -> Pipeline[StaticEvidence, WindowState]:
    """The pipeline of the evidence's kind."""
    if not ev.orientation_known:
        return ORIENTATION_FREE
    return STATIC if use_library else STATIC_NO_LIBRARY
