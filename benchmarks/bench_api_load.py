"""Dashboard readers that never pause against the live service while a run records at ×50.

``calbench serve --sim`` runs in its own process on 127.0.0.1 on SQLite (or PostgreSQL, below);
it starts the bench agent (``calbench agent``: sequencer, drivers, recording) as another
process, which starts the simulated table and Modbus DAQ in a third. The readers run in a fourth
(:mod:`benchmarks.load_readers`), so the client's CPU is measured apart from the service's. A
first short run gives the unit a history and a finished run to plot. Then:

* idle: one reader, the bench idle, ``BASELINE_CYCLES`` cycles of the same requests;
* load: a static-12 run at ×``SPEED`` simulated speed and ``RATE_HZ`` samples/s, with dwells
  long enough that it outlasts the load, ``READERS`` readers that fetch without pause what the
  run page and the overview read while a run is live (the run, the runs list, the units list,
  and, every fifth cycle, what opening a page fetches: the unit's history and trends, the
  finished run's plots, the service's health) for ``LOAD_S`` seconds, and half as many clients
  following the live run's event stream as the run page does. Readers revalidate with
  ``If-None-Match`` as the dashboard does.

``CALBENCH_LOAD_SECONDS`` sets the load's duration (180 s, the acceptance figure of
docs/benchmarks.md; 30 for a quick check), ``CALBENCH_LOAD_PAUSE_S`` the readers' pause between
cycles (0: never pause; a comma-separated list runs one loaded run per value).
``CALBENCH_LOAD_PG_URL`` (a PostgreSQL URL, ``postgresql+psycopg://user@host:port/db``, of a
database the user may ``CREATE DATABASE`` from) runs the service on PostgreSQL instead: in a
database ``calbench_load_<random>`` of that server, created for the benchmark and dropped after.

Printed: p50 / p99 latency per request kind and overall, idle and loaded in the same run and
their ratio; requests per second and the share answered 304; the CPU seconds of the service,
the agent (with its simulator) and the readers during the load; the load average; the run's
outcome, its recorded gaps, and a check of its recording (time stamps spaced 1/rate, the
database's chunk rows contiguous in sample numbers and adding up to the recording).
Loopback only, bounded loops.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import sqlalchemy as sa

from bench.recording import read_recording
from db.engine import make_engine
from db.models import SampleChunk
from tests.pg import pg_database

READERS = 50
SPEED = float(os.environ.get("CALBENCH_LOAD_SPEED", "50"))
RATE_HZ = 100.0
LOAD_S = float(os.environ.get("CALBENCH_LOAD_SECONDS", "180"))
PG_URL = os.environ.get("CALBENCH_LOAD_PG_URL", "")
"""A PostgreSQL server to run on (empty: SQLite in the benchmark's directory)."""
PAUSES_S = [float(x) for x in os.environ.get("CALBENCH_LOAD_PAUSE_S", "0").split(",")]
"""The readers' pause between cycles (s) of each loaded run; 0 = never pause."""
DWELL_S = max(30.0, 1.2 * LOAD_S * SPEED / 12)
"""Static dwell of the loaded run: its twelve windows outlast the load."""
BASELINE_CYCLES = 40
PAGE_EVERY = 5
OPERATOR = "operator-bench-load-0001"
VIEWER = "viewer-bench-load-0001"
FINAL = {"completed", "failed", "error", "aborted", "interrupted"}
SERIAL = "SN-LOAD-1"


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def _database(data_dir: Path) -> Iterator[str]:
    """The service's database URL: SQLite in ``data_dir``, or a fresh database on the server of
    :data:`PG_URL`, dropped on exit."""
    if not PG_URL:
        yield f"sqlite:///{data_dir / 'calbench.db'}"
        return
    with pg_database(PG_URL) as url:
        yield url


def _start_service(data_dir: Path, port: int, db_url: str) -> subprocess.Popen[bytes]:
    env = {
        **os.environ,
        "CALBENCH_DATA_DIR": str(data_dir),
        "CALBENCH_DATABASE_URL": db_url,
        "CALBENCH_TOKENS": f"operator:{OPERATOR},viewer:{VIEWER}",
        "CALBENCH_SIM_SAMPLE_RATE_HZ": str(RATE_HZ),
        "CALBENCH_DRIFT_TIME": "",
        "CALBENCH_BENCH_NAME": "bench-load",
    }
    cmd = [sys.executable, "-m", "api", "serve", "--sim", "--sim-speed", str(SPEED)]
    cmd += ["--port", str(port), "--log-level", "warning"]
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


def _start_run(c: httpx.Client, dwell_s: float) -> str:
    r = c.post(
        "/api/runs",
        json={"unit_serial": SERIAL, "procedure": "static-12", "dwell_s": dwell_s},
        headers={"Authorization": f"Bearer {OPERATOR}"},
    )
    r.raise_for_status()
    return str(r.json()["id"])


def _wait_state(c: httpx.Client, run_id: str, states: set[str], timeout_s: float) -> dict[str, Any]:
    """The run once its state is in ``states`` (and, for a final state, the bench is free)."""
    deadline = time.monotonic() + timeout_s
    body: dict[str, Any] = {}
    while time.monotonic() < deadline:
        body = c.get(f"/api/runs/{run_id}").json()
        if body.get("state") in states and (
            body["state"] not in FINAL or c.get("/api/health").json()["busy_run"] is None
        ):
            return body
        time.sleep(0.3)
    raise RuntimeError(f"run {run_id} did not reach {sorted(states)} within {timeout_s} s: {body}")


def _paths(live_id: str, done_id: str) -> tuple[list[list[str]], list[list[str]]]:
    """(what opening a page fetches, what the readers fetch every cycle)."""
    page = [
        ["history", f"/api/units/{SERIAL}/history"],
        ["trends", f"/api/units/{SERIAL}/plots/history"],
        ["g-check", f"/api/runs/{done_id}/plots/g-check"],
        ["residuals", f"/api/runs/{done_id}/plots/residuals"],
        ["allan", f"/api/runs/{done_id}/plots/allan"],
        ["health", "/api/health"],
    ]
    poll = [["run", f"/api/runs/{live_id}"], ["runs", "/api/runs?limit=20"], ["units", "/api/units"]]
    return page, poll


def _readers(port: int, data_dir: Path, name: str, **cfg: Any) -> dict[str, Any]:
    """Run :mod:`benchmarks.load_readers` in its own process with ``cfg``; its tally."""
    config = {"host": "127.0.0.1", "port": port, "token": VIEWER, "page_every": PAGE_EVERY, **cfg}
    cfg_path, out_path = data_dir / f"{name}.json", data_dir / f"{name}.out.json"
    cfg_path.write_text(json.dumps(config))
    subprocess.run(
        [sys.executable, "-m", "benchmarks.load_readers", str(cfg_path), str(out_path)], check=True
    )
    return dict(json.loads(out_path.read_text()))


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` (0 when it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _descendants(pid: int) -> list[int]:
    """Every process started by ``pid`` (by any of its threads) and by those, recursively."""
    out: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            children = (task / "children").read_text().split()
        except OSError:
            continue
        for child in map(int, children):
            out += [child, *_descendants(child)]
    return out


def _percentiles(lat: dict[str, list[float]]) -> dict[str, tuple[float, float, int]]:
    out = {k: (float(np.percentile(v, 50)), float(np.percentile(v, 99)), len(v)) for k, v in lat.items() if v}
    allv = [x for v in lat.values() for x in v]
    out["ALL"] = (float(np.percentile(allv, 50)), float(np.percentile(allv, 99)), len(allv))
    return out


def _gaps(recording: Path, db_url: str, run_id: str) -> str:
    rec = read_recording(str(recording))
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
        f"at {rec.sidecar.sample_rate_hz:g} Hz; time steps > 1.5/rate: {big.size} (largest step {worst}); "
        f"{len(rows)} chunk rows contiguous: {contiguous}, summing to {total} samples"
    )


def _load_phase(
    base: str,
    port: int,
    proc: subprocess.Popen[bytes],
    data_dir: Path,
    done_id: str,
    pause_s: float,
    idle: Any,
    db_url: str,
) -> None:
    """Start a ×SPEED run, load the service with READERS readers for LOAD_S s, print the results."""
    with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {VIEWER}"}, timeout=30.0) as c:
        live_id = _start_run(c, DWELL_S)
        _wait_state(c, live_id, {"running", *FINAL}, 120.0)
        page, poll = _paths(live_id, done_id)
        pids = {"service": [proc.pid], "agent+sim": _descendants(proc.pid)}
        cpu0 = {k: sum(map(_cpu_s, v)) for k, v in pids.items()}
        load0 = os.getloadavg()
        t0 = time.monotonic()
        tally = _readers(
            port,
            data_dir,
            f"load-{pause_s:g}",
            readers=READERS,
            duration_s=LOAD_S,
            pause_s=pause_s,
            page=page,
            poll=poll,
            followers=READERS // 2,
            events=f"/api/runs/{live_id}/events",
            followers_timeout_s=60.0 + 3.0 * 12 * (DWELL_S + 20.0) / SPEED,
        )
        cpu = {k: sum(map(_cpu_s, v)) - cpu0[k] for k, v in pids.items()}
        load1 = os.getloadavg()
        run = _wait_state(c, live_id, FINAL, 60.0 + 3.0 * 12 * (DWELL_S + 20.0) / SPEED)
    wall = tally["wall_s"]
    bp, lp = _percentiles(idle["latency_s"]), _percentiles(tally["latency_s"])
    n_req = lp["ALL"][2]
    n304 = tally["status"].get("304", 0)
    errors = tally["errors"]
    err = f" ({run.get('error')})" if run.get("error") else ""
    print(
        f"\n{READERS} readers pausing {pause_s:g} s between cycles for {wall:.1f} s; run {live_id} at "
        f"x{SPEED:g}, {RATE_HZ:g} Hz ended {run.get('state')}{err} "
        f"({time.monotonic() - t0:.0f} s after the load began)"
    )
    print(
        f"{n_req} requests, {n_req / wall:.0f} req/s, {n304 / max(n_req, 1):.0%} answered 304, "
        f"{len(errors)} errors" + (": " + ", ".join(sorted(set(errors))[:5]) if errors else "")
    )
    print(
        f"{READERS // 2} event streams: {tally['events'].get('progress', 0)} progress events in all, "
        f"{tally['events'].get('finished', 0)} saw the end"
    )
    print(
        f"load average (1 min) {load0[0]:.1f} at the start, {load1[0]:.1f} at the end; "
        "CPU s during the load: "
        + ", ".join(f"{k} {v:.1f}" for k, v in cpu.items())
        + f", readers {tally['cpu_s']:.1f} (of {2 * wall:.0f} on 2 cores)"
    )
    print(
        f"{'request':10s} {'idle p50 ms':>12s} {'load p50 ms':>12s} {'ratio':>7s} {'idle p99 ms':>12s} "
        f"{'load p99 ms':>12s} {'ratio':>7s}"
    )
    for k in [*(k for k, _ in [*poll, *page]), "ALL"]:
        if k in lp and k in bp:
            (b50, b99, _), (l50, l99, _) = bp[k], lp[k]
            print(
                f"{k:10s} {b50 * 1e3:12.2f} {l50 * 1e3:12.2f} {l50 / b50:7.1f} {b99 * 1e3:12.2f} "
                f"{l99 * 1e3:12.2f} {l99 / b99:7.1f}"
            )
    lost = run.get("n_samples_lost")
    print(f"gaps the run recorded: {len(run.get('gaps') or [])} ({lost} samples lost)")
    rec_path = data_dir / "recordings" / f"run-{live_id}.csv"
    if rec_path.exists():
        print("recording:", _gaps(rec_path, db_url, live_id))
    else:
        print(f"recording: {rec_path} not found")


def main() -> None:
    """A finished run to read, the idle baseline, then one loaded run per pause of PAUSES_S."""
    with tempfile.TemporaryDirectory(prefix="calbench-load-") as d, _database(Path(d)) as db_url:
        data_dir = Path(d)
        port = _free_port()
        base = f"http://127.0.0.1:{port}"
        proc = _start_service(data_dir, port, db_url)
        try:
            _wait_up(base, proc)
            with httpx.Client(
                base_url=base, headers={"Authorization": f"Bearer {VIEWER}"}, timeout=30.0
            ) as c:
                done_id = _start_run(c, 3.0)
                first = _wait_state(c, done_id, FINAL, 300.0)
            if first.get("state") != "completed":
                raise RuntimeError(f"the first run did not complete: {json.dumps(first)[:300]}")
            page, poll = _paths(done_id, done_id)
            idle = _readers(
                port, data_dir, "idle", readers=1, cycles=BASELINE_CYCLES, duration_s=600.0, pause_s=0.0,
                page=page, poll=poll,
            )  # fmt: skip
            print(
                f"database {sa.make_url(db_url).get_backend_name()}; "
                f"idle baseline: one reader, {BASELINE_CYCLES} cycles, bench idle, "
                f"load average {os.getloadavg()[0]:.1f}"
            )
            for pause_s in PAUSES_S:
                _load_phase(base, port, proc, data_dir, done_id, pause_s, idle, db_url)
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=30.0)
            except subprocess.TimeoutExpired:
                proc.kill()
