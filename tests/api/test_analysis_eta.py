"""The time left includes the analysis after the recording, as its own phase: a run's events
carry ``analysis_s``, the analysis wall time expected from this bench's past runs of the
procedure (:mod:`station.runs.analysis_eta`: their median), and when the recording ends the predicted finish
(then + ``analysis_s``) is close to the actual one.

Through the real service (TestClient, its embedded agent, the simulated bench at the service
tests' speed, SQLite): static-12 runs one after another on one bench, each on its own unit; the
events the agent publishes are timed as they leave it. The first run has no history
(``analysis_s`` is ``None`` throughout: unknown, not guessed); each later one predicts its
analysis from the runs before: the median of what the earlier runs' final events stored. How
close the prediction comes to the actual analysis is wall time on a machine whose load varies:
a rate over runs, measured by
``benchmarks/bench_eta_analysis.py`` (docs/benchmarks.md), not asserted here.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from station.runs.analysis_eta import AnalysisPace, pace_from
from tests.support.service_helpers import OP, service_settings, wait_final

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1200)]

RUNS = 3


def test_the_expected_analysis_is_the_median_of_the_past_ones() -> None:
    pace = pace_from([10.0, 30.0, 4.0, 0.0, -1.0])
    assert pace == AnalysisPace(10.0, 3)  # 4, 10, 30 s; empty entries skipped
    assert pace.expected_s() == 10.0
    assert pace_from([]) is None and pace_from([0.0]) is None


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, list[Any]]]:
    settings = service_settings(tmp_path_factory.mktemp("eta"), bench_name="bench-eta")
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        hub = c.app.state.services.agent.runner.hub  # type: ignore[attr-defined]
        events: list[tuple[float, str, str, dict[str, Any]]] = []
        publish = hub.publish

        def timed(run_id: str, event: str, data: dict[str, Any]) -> None:
            events.append((time.monotonic(), run_id, event, dict(data)))
            publish(run_id, event, data)

        hub.publish = timed
        yield c, events


def test_the_eta_at_the_end_of_the_recording_includes_the_analysis(
    served: tuple[TestClient, list[Any]],
) -> None:
    client, events = served
    rows = []
    for i in range(RUNS):
        r = client.post(
            "/api/runs", json={"unit_serial": f"SN-ETA-{i}", "procedure": "static-12"}, headers=OP
        )
        assert r.status_code == 202, r.text
        run_id = r.json()["id"]
        assert wait_final(client, run_id, timeout_s=900.0)["state"] == "completed"
        mine = [(t, n, d) for t, rid, n, d in events if rid == run_id]
        recording = [d for _, n, d in mine if n == "progress" and d.get("phase") == "recording"]
        t_end, at_end = next((t, d) for t, n, d in mine if n == "progress" and d.get("phase") == "analysing")
        t_done, done = next((t, d) for t, n, d in mine if n == "finished")
        predicted, actual = at_end.get("analysis_s"), t_done - t_end
        stored = done["analysis_wall_s"]  # what the next run learns from
        assert isinstance(stored, float) and stored > 0, done
        if i == 0:  # no analysed run of static-12 on this bench yet: unknown, not guessed
            assert predicted is None and all(d.get("analysis_s") is None for d in recording)
        else:
            assert isinstance(predicted, float) and predicted > 0
            assert isinstance(recording[-1].get("analysis_s"), float)  # shown while recording
            earlier = statistics.median(a for _, _, a in rows)
            assert predicted == pytest.approx(earlier, abs=1e-3), (i, predicted, rows)
        rows.append((predicted, actual, stored))
    print("analysis predicted / actual (s):", rows)
