"""50 dashboard readers against the live service while a run records at ×50 speed.

``calbench serve --sim`` runs in its own process on 127.0.0.1; it starts the bench agent
(``calbench agent``: sequencer, drivers, recording) as another process, which starts the
simulated table and Modbus DAQ in a third, as in a lab where the web server and the bench
share a machine but not a process. A first short run gives the unit a history and a finished
run to plot. Then:

* baseline: one reader, the bench idle, the same request mix;
* load: a static-12 run at ×``SPEED`` simulated speed and ``RATE_HZ`` samples/s, with dwells
  long enough that it outlasts the load, and ``READERS`` threads polling what the dashboard
  polls (runs list, the run, units, unit history, the finished run's plot series, health),
  for ``LOAD_LIMIT_S`` seconds (``CALBENCH_LOAD_SECONDS``: 60 by default in ``make bench``,
  180 for the acceptance figure in docs/benchmarks.md); half as many clients follow the run's
  event stream as the run page does.

Printed: p50 / p99 latency per request kind and overall, as ratios against the idle
baseline of the same run, and whether the run's recording has gaps (time stamps spaced
1/rate, the database's chunk rows contiguous in sample numbers and adding up to the
recording). Loopback only, bounded loops.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path

import httpx
import numpy as np
import sqlalchemy as sa

from bench.recording import read_recording
from db.engine import make_engine
from db.models import SampleChunk

READERS = 50
SPEED = float(os.environ.get("CALBENCH_LOAD_SPEED", "50"))
RATE_HZ = 100.0
LOAD_LIMIT_S = float(os.environ.get("CALBENCH_LOAD_SECONDS", "60"))
DWELL_S = max(60.0, 1.2 * LOAD_LIMIT_S * SPEED / 12)
"""Static dwell of the loaded run: its twelve windows outlast the load."""
POLL_S = 3.0
"""The dashboard's overview polls every 3 s (``view_overview.js``); the run page follows the stream."""
POLLS_S = [float(x) for x in os.environ.get("CALBENCH_LOAD_POLLS", f"{POLL_S:g},0").split(",")]
"""The load phases: the readers' pause between cycles (s), 0 = never pause."""
BASELINE_CYCLES = 40
OPERATOR = "operator-bench-load-0001"
VIEWER = "viewer-bench-load-0001"
FINAL = {"completed", "failed", "error", "aborted", "interrupted"}


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _start_service(data_dir: Path, port: int) -> subprocess.Popen[bytes]:
    env = {
        **os.environ,
        "CALBENCH_DATA_DIR": str(data_dir),
        "CALBENCH_DATABASE_URL": f"sqlite:///{data_dir / 'calbench.db'}",
        "CALBENCH_TOKENS": f"operator:{OPERATOR},viewer:{VIEWER}",
        "CALBENCH_SIM_SAMPLE_RATE_HZ": str(RATE_HZ),
        "CALBENCH_DRIFT_TIME": "",
        "CALBENCH_BENCH_NAME": "bench-load",
    }
    cmd = [
        sys.executable,
        "-m",
        "api",
        "serve",
        "--sim",
        "--sim-speed",
        str(SPEED),
        "--port",
        str(port),
        "--log-level",
        "warning",
    ]
    log = (data_dir / "serve.log").open("wb")
    return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)


def _wait_up(base: str, proc: subprocess.Popen[bytes], timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"calbench serve exited with {proc.returncode}")
        try:
            if httpx.get(f"{base}/api/health", timeout=2.0).status_code == 200:
                return
        except httpx.TransportError:
            pass
        time.sleep(0.2)
    raise RuntimeError(f"calbench serve did not answer on {base} within {timeout_s} s")


def _start_run(c: httpx.Client, serial: str, dwell_s: float) -> str:
    r = c.post(
        "/api/runs",
        json={"unit_serial": serial, "procedure": "static-12", "dwell_s": dwell_s},
        headers={"Authorization": f"Bearer {OPERATOR}"},
    )
    r.raise_for_status()
    return str(r.json()["id"])


def _wait_final(c: httpx.Client, run_id: str, timeout_s: float) -> dict[str, object]:
    deadline = time.monotonic() + timeout_s
    body: dict[str, object] = {}
    while time.monotonic() < deadline:
        body = c.get(f"/api/runs/{run_id}").json()
        if body.get("state") in FINAL and c.get("/api/health").json()["busy_run"] is None:
            return body
        time.sleep(0.3)
    raise RuntimeError(f"run {run_id} did not finish within {timeout_s} s: {body}")


def _paths(serial: str, live_id: str, done_id: str) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """(what a page load fetches once, what the open page polls)."""
    load = [
        ("history", f"/api/units/{serial}/history"),
        ("trends", f"/api/units/{serial}/plots/history"),
        ("g-check", f"/api/runs/{done_id}/plots/g-check"),
        ("residuals", f"/api/runs/{done_id}/plots/residuals"),
        ("allan", f"/api/runs/{done_id}/plots/allan"),
    ]
    poll = [
        ("runs", "/api/runs?limit=20"),
        ("run", f"/api/runs/{live_id}"),
        ("units", "/api/units"),
        ("health", "/api/health"),
    ]
    return load, poll


def _reader(
    base: str,
    paths: tuple[list[tuple[str, str]], list[tuple[str, str]]],
    stop: threading.Event,
    cycles: int | None,
    poll_s: float,
    out: dict[str, list[float]],
    errors: list[str],
    lock: threading.Lock,
) -> None:
    """A dashboard reader: every ``poll_s`` (0: without pause) it fetches what the pages poll and,
    every fifth cycle, what a page load fetches (history, trends, plots)."""
    local: dict[str, list[float]] = defaultdict(list)
    n = 0
    rng = np.random.default_rng(threading.get_ident() % (2**32))
    with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {VIEWER}"}, timeout=30.0) as c:
        time.sleep(float(rng.uniform(0.0, poll_s)))  # readers do not arrive in lock step
        while not stop.is_set() and (cycles is None or n < cycles):
            t_cycle = time.perf_counter()
            for kind, path in [*paths[0], *paths[1]] if n % 5 == 0 else paths[1]:
                t0 = time.perf_counter()
                try:
                    r = c.get(path)
                    if r.status_code != 200:
                        errors.append(f"{kind}: HTTP {r.status_code}")
                except httpx.HTTPError as exc:
                    errors.append(f"{kind}: {type(exc).__name__}")
                local[kind].append(time.perf_counter() - t0)
            n += 1
            stop.wait(max(0.0, poll_s - (time.perf_counter() - t_cycle)))
    with lock:
        for k, v in local.items():
            out[k].extend(v)


def _follow_events(base: str, run_id: str, counts: dict[str, int]) -> None:
    """A run page's event stream, followed to its end; counts the events by name (all followers)."""
    with (
        httpx.Client(base_url=base, headers={"Authorization": f"Bearer {VIEWER}"}, timeout=60.0) as c,
        c.stream("GET", f"/api/runs/{run_id}/events") as r,
    ):
        for line in r.iter_lines():
            if line.startswith("event:"):
                name = line[6:].strip()
                counts[name] = counts.get(name, 0) + 1
                if name == "finished":
                    return


def _percentiles(lat: dict[str, list[float]]) -> dict[str, tuple[float, float, int]]:
    out = {k: (float(np.percentile(v, 50)), float(np.percentile(v, 99)), len(v)) for k, v in lat.items() if v}
    allv = [x for v in lat.values() for x in v]
    out["ALL"] = (float(np.percentile(allv, 50)), float(np.percentile(allv, 99)), len(allv))
    return out


def _gaps(recording: str, db_url: str, run_id: str) -> str:
    rec = read_recording(recording)
    dt = np.diff(rec.t_s)
    step = 1.0 / rec.sidecar.sample_rate_hz
    big = np.flatnonzero(dt > 1.5 * step)
    engine = make_engine(db_url)
    with engine.connect() as conn:
        rows = conn.execute(
            sa.select(SampleChunk.first_sample, SampleChunk.n_samples)
            .where(SampleChunk.run_id == run_id)
            .order_by(SampleChunk.seq)
        ).all()
    engine.dispose()
    starts = np.array([r[0] for r in rows])
    sizes = np.array([r[1] for r in rows])
    contiguous = bool(np.all(starts[1:] == starts[:-1] + sizes[:-1])) and (starts[0] == 0 if rows else False)
    total = int(sizes.sum()) if rows else 0
    verdict = "NO GAPS" if (big.size == 0 and contiguous and total == rec.n_samples) else "GAPS"
    worst = f"{dt.max() * 1e3:.3f} ms" if dt.size else "-"
    return (
        f"{verdict}: {rec.n_samples} samples over {rec.t_s[-1] - rec.t_s[0]:.1f} s "
        f"at {rec.sidecar.sample_rate_hz:g} Hz; "
        f"time steps > 1.5/rate: {big.size} (largest step {worst}); "
        f"{len(rows)} chunk rows contiguous: {contiguous}, summing to {total} samples"
    )


def _load_phase(
    base: str, data_dir: Path, serial: str, done_id: str, poll_s: float, base_lat: dict[str, list[float]]
) -> None:
    """Start a ×SPEED run, let READERS readers poll every ``poll_s`` until it ends, print the results."""
    with httpx.Client(base_url=base, timeout=30.0) as c:
        live_id = _start_run(c, serial, DWELL_S)
    paths = _paths(serial, live_id, done_id)
    lat: dict[str, list[float]] = defaultdict(list)
    errors: list[str] = []
    lock = threading.Lock()
    stop = threading.Event()
    events: dict[str, int] = {}
    readers = [
        threading.Thread(target=_reader, args=(base, paths, stop, None, poll_s, lat, errors, lock))
        for _ in range(READERS)
    ]
    followers = [
        threading.Thread(target=_follow_events, args=(base, live_id, events), daemon=True)
        for _ in range(READERS // 2)
    ]
    t0 = time.perf_counter()
    for th in [*followers, *readers]:
        th.start()
    with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {VIEWER}"}, timeout=30.0) as c:
        while time.perf_counter() - t0 < LOAD_LIMIT_S:
            if c.get(f"/api/runs/{live_id}").json().get("state") in FINAL:
                break
            time.sleep(0.5)
        stop.set()
        for th in readers:
            th.join(timeout=60.0)
        wall = time.perf_counter() - t0
        run = _wait_final(c, live_id, 60.0 + 3.0 * 12 * (DWELL_S + 20.0) / SPEED)
        for th in followers:
            th.join(timeout=30.0)
    bp, lp = _percentiles(base_lat), _percentiles(lat)
    n_req = lp["ALL"][2]
    err = f" ({run.get('error')})" if run.get("error") else ""
    print(
        f"\n{READERS} readers polling every {poll_s:g} s for {wall:.1f} s; run {live_id} at x{SPEED:g}, "
        f"{RATE_HZ:g} Hz ended {run.get('state')}{err}"
    )
    print(
        f"{n_req} requests, {n_req / wall:.0f} req/s, {len(errors)} errors"
        + (": " + ", ".join(sorted(set(errors))[:5]) if errors else "")
    )
    print(
        f"{READERS // 2} event streams: {events.get('progress', 0)} progress events in all, "
        f"{events.get('finished', 0)} saw the end"
    )
    print(
        f"{'request':10s} {'idle p50 ms':>12s} {'load p50 ms':>12s} {'ratio':>7s} {'idle p99 ms':>12s} "
        f"{'load p99 ms':>12s} {'ratio':>7s}"
    )
    for k in [*(k for k, _ in [*paths[0], *paths[1]]), "ALL"]:
        if k in lp and k in bp:
            (b50, b99, _), (l50, l99, _) = bp[k], lp[k]
            print(
                f"{k:10s} {b50 * 1e3:12.2f} {l50 * 1e3:12.2f} {l50 / b50:7.1f} {b99 * 1e3:12.2f} "
                f"{l99 * 1e3:12.2f} {l99 / b99:7.1f}"
            )
    rec_path = data_dir / "recordings" / f"run-{live_id}.csv"
    if rec_path.exists():
        print("recording:", _gaps(str(rec_path), f"sqlite:///{data_dir / 'calbench.db'}", live_id))
    else:
        print(f"recording: {rec_path} not found")


def main() -> None:
    """Idle baseline, then the dashboard's own polling rate, then readers that never pause."""
    with tempfile.TemporaryDirectory(prefix="calbench-load-") as d:
        data_dir = Path(d)
        port = _free_port()
        base = f"http://127.0.0.1:{port}"
        proc = _start_service(data_dir, port)
        try:
            _wait_up(base, proc)
            serial = "SN-LOAD-1"
            with httpx.Client(
                base_url=base, headers={"Authorization": f"Bearer {VIEWER}"}, timeout=30.0
            ) as c:
                done_id = _start_run(c, serial, 3.0)
                first = _wait_final(c, done_id, 300.0)
            if first.get("state") != "completed":
                raise RuntimeError(f"the first run did not complete: {json.dumps(first)[:300]}")
            base_lat: dict[str, list[float]] = defaultdict(list)
            _reader(
                base,
                _paths(serial, done_id, done_id),
                threading.Event(),
                BASELINE_CYCLES,
                0.0,
                base_lat,
                [],
                threading.Lock(),
            )
            print(f"idle baseline: one reader, {BASELINE_CYCLES} cycles, bench idle")
            for poll_s in POLLS_S:
                _load_phase(base, data_dir, serial, done_id, poll_s, base_lat)
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=30.0)
            except subprocess.TimeoutExpired:
                proc.kill()
