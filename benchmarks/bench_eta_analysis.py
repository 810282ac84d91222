"""How well the time left predicts the finish once the recording is over: the analysis phase.

Service runs (the real app in this process, its embedded agent, the simulated bench at
``SPEED`` × real time and ``RATE_HZ`` samples/s as in :mod:`benchmarks.bench_eta`, SQLite) of one
procedure, one after another on one bench, each on its own unit (the diagnosis's work differs
with what a unit's recording holds). At the event that ends the recording the service predicts
the analysis's wall time from the bench's earlier runs of the procedure
(:mod:`station.runs.analysis_eta`: the median of their analysis times); the truth is the time
from that event to the run's ``finished`` event (results and certificate stored), both timed as
the agent publishes them.

Printed per run: the recording's length (recording clock), predicted and actual analysis (s),
their relative error (actual − predicted) / actual; then the median and largest |error| over
the runs that had a prediction. ``python -m benchmarks.bench_eta_analysis --runs 6``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient

from api.main import create_app
from tests.support.service_helpers import OP, service_settings

SPEED = 20.0
RATE_HZ = 250.0


def one_run(
    client: TestClient, events: list[Any], procedure: str, serial: str
) -> tuple[float, float | None, float]:
    """(recording s, predicted analysis s or None, actual analysis s) of one service run, from
    the agent's events as they leave it (timed by :func:`timed_hub`)."""
    r = client.post("/api/runs", json={"unit_serial": serial, "procedure": procedure}, headers=OP)
    r.raise_for_status()
    run_id = r.json()["id"]
    deadline = time.monotonic() + 3600.0

    def ended() -> bool:  # a device fault's "finished" (interrupted) is followed by its resume
        return any(
            rid == run_id and n == "finished" and d.get("state") != "interrupted" for _, rid, n, d in events
        )

    while not ended():
        if time.monotonic() > deadline:
            raise RuntimeError(f"{run_id}: not finished within an hour")
        time.sleep(0.2)
    mine = [(t, n, d) for t, rid, n, d in events if rid == run_id]
    t_done, done = [(t, d) for t, n, d in mine if n == "finished"][-1]
    t_end, at_end = [(t, d) for t, n, d in mine if n == "progress" and d.get("phase") == "analysing"][-1]
    if done.get("state") != "completed":
        raise RuntimeError(f"{run_id}: {done.get('state')} {done.get('error')}")
    recording_s = max((float(d.get("elapsed_s", 0.0)) for _, n, d in mine if n == "progress"), default=0.0)
    return recording_s, at_end.get("analysis_s"), t_done - t_end


def timed_hub(client: TestClient) -> list[Any]:
    """Every event the embedded agent publishes, with the monotonic time it left it."""
    hub = client.app.state.services.agent.runner.hub  # type: ignore[attr-defined]
    events: list[tuple[float, str, str, dict[str, Any]]] = []
    publish = hub.publish

    def timed(run_id: str, event: str, data: dict[str, Any]) -> None:
        events.append((time.monotonic(), run_id, event, dict(data)))
        publish(run_id, event, data)

    hub.publish = timed
    return events


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_eta_analysis")
    parser.add_argument("--runs", type=int, default=6)
    parser.add_argument("--procedure", default="static-12")
    parser.add_argument("--dwell-s", type=float, default=5.0)
    args = parser.parse_args(argv or [])
    print(f"{args.procedure}, service runs at ×{SPEED:g}, {RATE_HZ:g} Hz, dwell {args.dwell_s:g} s")
    print(f"{'run':>3} {'recording':>10} {'predicted':>10} {'actual':>8} {'error':>8}   load")
    errors = []
    with tempfile.TemporaryDirectory() as tmp:
        settings = service_settings(
            Path(tmp),
            sim_speed=SPEED,
            sim_sample_rate_hz=RATE_HZ,
            run_dwell_s=args.dwell_s,
            bench_name="bench-eta",
        )
        with TestClient(create_app(settings, start_scheduler=False)) as client:
            events = timed_hub(client)
            for i in range(args.runs):
                n, predicted, actual = one_run(client, events, args.procedure, f"SN-ETA-A{i}")
                err = None if predicted is None else (actual - predicted) / actual
                if err is not None:
                    errors.append(abs(err))
                shown = "–" if predicted is None else f"{predicted:.1f} s"
                cell = "–" if err is None else f"{100 * err:+.0f} %"
                load = os.getloadavg()[0]
                print(f"{i:>3} {n:>8.0f} s {shown:>10} {actual:>6.1f} s {cell:>8}   {load:.1f}", flush=True)
    if errors:
        print(
            f"|error| of the predicted analysis: median {100 * statistics.median(errors):.0f} %, "
            f"largest {100 * max(errors):.0f} % over {len(errors)} runs"
        )


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
