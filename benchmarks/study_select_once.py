"""How often the window-means selection resumes, and what it selects (docs/diagnose.md, "Where
the one method is not yet one").

``python -m benchmarks.study_select_once [N]``: the selection stages of the static pipeline
(``stages.pipeline_for``, from screen_catalogue to out_of_sample_referee) on N seeds (1…) of
the library cases ``cubic`` and ``scale_temperature`` (``benchmarks.library_cases``) and N/2
seeds (100…) of a hand-held session with a 4e-3 V/g³ cube on ax
(``benchmarks.study_diagnose_one_channel``). Prints one line per recording: the CPU time of
the stages, how often the selection resumed (``Selection.without``) and the referee ran, the
catalogue effects taken out and the selected model; then the totals. A start from scratch
would have run ``select`` once more for every resume.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

from bench.calibration.diagnose import recording_evidence
from bench.diagnosis import check_stages, head_to_head_stage, stages
from bench.diagnosis import referee as referee_module
from bench.diagnosis.selection import Selection
from bench.diagnosis.thresholds import THRESHOLDS
from bench.diagnosis.window_state import WindowState
from bench.recording import Recording
from benchmarks.library_cases import CASES
from benchmarks.study_diagnose_one_channel import cubic, hand_held, tableless

COUNTS = {"resumed": 0, "referee": 0}


def _counted(key: str, f: Callable[..., Any]) -> Callable[..., Any]:
    def g(*args: Any, **kwargs: Any) -> Any:
        COUNTS[key] += 1
        return f(*args, **kwargs)

    return g


def recordings(n: int) -> Iterator[tuple[str, Callable[[], Recording]]]:
    """(label, recording maker) of the study's recordings."""
    for seed in range(1, 1 + n):
        for name in ("cubic", "scale_temperature"):
            yield f"{name} {seed}", lambda name=name, seed=seed: CASES[name].recording(seed)  # type: ignore[misc]
    for seed in range(100, 100 + max(n // 2, 1)):
        yield f"hand-held cube {seed}", lambda seed=seed: tableless(cubic(hand_held(seed), 0, 4e-3))  # type: ignore[misc]


def main(n: int) -> None:
    """Print the lines of the module docstring."""
    Selection.without = _counted("resumed", Selection.without)  # type: ignore[method-assign]
    counted = _counted("referee", referee_module.referee)
    for module in (check_stages, head_to_head_stage):
        setattr(module, "referee", counted)  # noqa: B010
    total = {"recordings": 0, "resumed": 0, "referee": 0, "cpu_s": 0.0}
    for label, make in recordings(n):
        ev = recording_evidence(make())
        COUNTS.update(resumed=0, referee=0)
        st = WindowState()
        t0 = time.process_time()
        for stage in stages.pipeline_for(ev).stages:
            st, notes = stage(ev, st, THRESHOLDS)
            st = st.noted(notes)
            if stage is check_stages.out_of_sample_referee:
                break
        cpu = time.process_time() - t0
        assert st.model is not None
        model = [c.label for c in st.model.candidates] + (["pose_error"] if st.model.pose else [])
        print(
            f"{label}: {cpu:.1f} s, resumed {COUNTS['resumed']}, referee {COUNTS['referee']}, "
            f"taken out {sorted(st.excluded)}, model {model}",
            flush=True,
        )
        total["recordings"] += 1
        total["resumed"] += COUNTS["resumed"]
        total["referee"] += COUNTS["referee"]
        total["cpu_s"] += cpu
    print(f"total: {total}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 8)
