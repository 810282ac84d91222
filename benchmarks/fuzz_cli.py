"""Mutation fuzzer of the CLI: mutants of one valid recording, each through ``calibrate`` and ``diagnose``.

``python -m benchmarks.fuzz_cli [N_MUTANTS] [SEED] [--moving] [--progress] [--deadline-s=S] [--first=I]``
(``make fuzz``) writes a small static-12 recording with ``calbench simulate``, makes N_MUTANTS
(default 800) mutants of its CSV and sidecar (number spellings Python's ``float()`` reads but a
recording must not, huge and non-finite numbers, huge fields, deep nesting,
deleted/duplicated/swapped rows, truncation, byte flips, wrong types and units, offsets of the table
angles, rates that disagree with the time column, text with NUL and bidi controls, a missing
sidecar...) and runs both commands on each with ``--json``. ``--moving`` fuzzes a rate-1axis
recording (50 Hz) instead, with the faults a real table and DAQ have among its mutants
(:func:`mutate_moving`: spikes, clipping, rounded and lagging encoders, a channel scaled or its sign
flipped), and a warning counts only when it is in the JSON's ``warnings``. Every outcome is
classified:

- ``traceback``: an exception escaped ``calbench``'s ``main`` (a bug);
- ``hang``: no answer within the time limit (a bug): :data:`TIMEOUT_S` of CPU time;
- ``exit2 multi-line``: bad input reported on more than one stderr line (a bug);
- ``silent``: exit 0, but the calibration moved beyond its own uncertainty (any bias or K
  element by more than 5 σ, σ the larger of the two runs') while neither the residual grew
  (chi²/dof or rms by more than 2×) nor a warning was printed (a bug: a wrong answer that
  looks right);
- ``moved, equivalent``: as ``silent``, but the mutant is a valid recording of another setup
  (the innermost axis's encoder zero moved by less than the 5° that ``calibrate`` warns about:
  exactly the data of a sensor mounted turned by that angle, so no residual can show it; the
  moved K is that sensor's right answer);
- ``exit2``, ``ok``, ``ok, flagged`` (exit 0 with a warning or a grown residual): fine.

The commands run in a worker process that imports calbench once and calls ``api.cli.main``;
the parent kills and restarts it when a case passes the time limit. The exit status is 1 when
any case is a bug. Results go to docs/benchmarks.md.
"""

from __future__ import annotations

import contextlib
import io
import json
import multiprocessing as mp
import os
import random
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import numpy as np

TIMEOUT_S = 120.0
"""A command that used more CPU time than this (s, the worker's user + system time) hangs."""
WALL_LIMIT_S = 1800.0
"""...or that has not answered after this wall time (s): on a shared machine the wall time of a
command is mostly the other users' (at a load of 20 on 2 cores, 8x its CPU time), so the limit is
on CPU time, with the wall time only as a backstop (and the limit where /proc is missing)."""
EQUIVALENT = "innermost axis: the recording of a sensor mounted turned by that angle"
"""An offset of the innermost axis's encoder is a rotation of the sensor about that axis: the same
data as a valid recording of a differently mounted sensor, whose right answer is a turned K."""
SIGMA_LIMIT = 5.0
RESIDUAL_GROWTH = 2.0

WEIRD_NUMBERS = [
    "1_0",
    "١٢",
    "１",
    "٣.٥",
    "1e999",
    "-1e999",
    "nan",
    "NaN",
    "inf",
    "-Infinity",
    "0x10",
    "1e",
    "--1",
    "",
    " ",
    "1.5.2",
    "1,5",
    "+",
    ".",
    "1d5",
    "9" * 400,
    "1e-400",
    "1e308",
    "-0",
    "\u00a01",
    "1\u200b",
    "\x00",
    '"1"',
    "'1'",
    "1 2",
    "true",
    "null",
    "\u202e1",
    "1" * 200_000,
]
WEIRD_JSON = [
    None,
    True,
    [],
    {},
    "",
    " ",
    "x",
    "١٢",
    -1,
    0,
    1e-300,
    1e300,
    10**400,
    [1, 2],
    {"a": 1},
    "\u202eSN",
    "SN\x00",
    "A" * 100_000,
]


def _lines(text: str) -> list[str]:
    return text.split("\n")


def mutate_csv(csv: str, rng: random.Random) -> tuple[str, str]:
    """One mutation of the CSV text; returns (new text, description)."""
    lines = _lines(csv)
    header, body = lines[0], [ln for ln in lines[1:] if ln]
    n_cols = len(header.split(","))
    kind = rng.choice(
        [
            "field",
            "field",
            "field",
            "delete",
            "duplicate",
            "swap",
            "blank",
            "truncate",
            "flip",
            "header",
            "extra_col",
            "drop_col",
            "angle_offset",
            "time_scale",
            "time_shift",
            "bom",
            "crlf",
            "quote",
        ]
    )
    r = rng.randrange(len(body))
    if kind == "field":
        cells = body[r].split(",")
        c = rng.randrange(n_cols)
        cells[c] = rng.choice(WEIRD_NUMBERS)
        body[r] = ",".join(cells)
        desc = f"row {r + 1} column {c + 1} = {cells[c][:20]!r}"
    elif kind == "delete":
        k = rng.randint(1, 50)
        del body[r : r + k]
        desc = f"delete {k} rows at {r + 1}"
    elif kind == "duplicate":
        body.insert(r, body[r])
        desc = f"duplicate row {r + 1}"
    elif kind == "swap":
        s = rng.randrange(len(body))
        body[r], body[s] = body[s], body[r]
        desc = f"swap rows {r + 1} and {s + 1}"
    elif kind == "blank":
        body.insert(r, "")
        desc = f"blank line before row {r + 1}"
    elif kind == "truncate":
        text = "\n".join([header, *body]) + "\n"
        cut = rng.randrange(len(text))
        return text[:cut], f"truncate at byte {cut}"
    elif kind == "flip":
        raw = bytearray(("\n".join([header, *body]) + "\n").encode())
        i = rng.randrange(len(raw))
        raw[i] = rng.randrange(256)
        return raw.decode("utf-8", "surrogateescape"), f"byte {i} = {raw[i]}"
    elif kind == "header":
        names = header.split(",")
        c = rng.randrange(len(names))
        names[c] = rng.choice(["", "t", "ax", "table_9", "x" * 70_000, "a\x00", "gx", " ax "])
        header = ",".join(names)
        desc = f"header column {c + 1} renamed"
    elif kind == "extra_col":
        header += ",note"
        body = [b + "," + rng.choice(["x", "1_0", "\u202e", "\x00", '"a,b"']) for b in body]
        desc = "extra text column"
    elif kind == "drop_col":
        c = rng.randrange(n_cols)
        header = ",".join(v for i, v in enumerate(header.split(",")) if i != c)
        body = [",".join(v for i, v in enumerate(b.split(",")) if i != c) for b in body]
        desc = f"drop column {c + 1}"
    elif kind == "angle_offset":
        names = header.split(",")
        cols = [i for i, n in enumerate(names) if n.startswith("table_")]
        c = rng.choice(cols)
        off = rng.choice([360.0, 720.0, 1e10, -1e10, 0.5, 90.0, 1e6 + 1])
        out = []
        for b in body:
            cells = b.split(",")
            cells[c] = repr(float(cells[c]) + off)
            out.append(",".join(cells))
        body = out
        desc = f"column {names[c]} offset by {off:g} deg"
        if c == cols[-1]:
            desc += f" ({EQUIVALENT})"
    elif kind == "time_scale":
        f = rng.choice([1e-300, 1e-6, 0.5, 2.0, 1e6, 1e300, -1.0])
        out = []
        for b in body:
            cells = b.split(",")
            cells[0] = repr(float(cells[0]) * f)
            out.append(",".join(cells))
        body = out
        desc = f"time scaled by {f:g}"
    elif kind == "time_shift":
        cells = body[r].split(",")
        cells[0] = repr(float(cells[0]) + rng.choice([-1.0, 1e-9, 100.0]))
        body[r] = ",".join(cells)
        desc = f"row {r + 1} time shifted"
    elif kind == "bom":
        return "\ufeff" + "\n".join([header, *body]) + "\n", "byte order mark"
    elif kind == "crlf":
        return "\r\n".join([header, *body]) + "\r\n", "CRLF line ends"
    else:
        cells = body[r].split(",")
        cells[rng.randrange(n_cols)] = '"1'
        body[r] = ",".join(cells)
        desc = f"unterminated quote in row {r + 1}"
    return "\n".join([header, *body]) + "\n", desc


def _columns(csv: str) -> tuple[list[str], np.ndarray]:
    lines = [ln for ln in _lines(csv) if ln]
    names = lines[0].split(",")
    data = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]], dtype=float)
    return names, data


def _csv(names: list[str], data: np.ndarray) -> str:
    rows = [",".join(repr(float(v)) for v in row) for row in data]
    return "\n".join([",".join(names), *rows]) + "\n"


MOVING_KINDS = (
    "spikes", "spike", "burst", "clip", "encoder_round", "encoder_lag", "channel_scale", "channel_sign", "csv"
)  # fmt: skip
"""Mutations of a moving recording: faults a real table and DAQ have (``csv``: one of :func:`mutate_csv`)."""


def mutate_moving(csv: str, rng: random.Random) -> tuple[str, str]:
    """One physical fault in a moving recording's data; returns (new text, description).

    spikes: 1–30 single samples of one channel moved by 10–1000 times the channel's noise;
    burst: a few consecutive samples; clip: one channel stuck at a rail below its peak;
    encoder_round: every table angle rounded to 0.05–1°; encoder_lag: the encoder columns
    delayed by 2–40 samples against the DAQ; channel_scale: one channel multiplied by 1e3–1e6;
    channel_sign: one channel's sign flipped (a mirror image)."""
    kind = rng.choice(MOVING_KINDS)
    if kind == "csv":
        text, desc = mutate_csv(csv, rng)
        return text, f"csv: {desc}"
    names, data = _columns(csv)
    n = len(data)
    acc = [names.index(c) for c in ("ax", "ay", "az")]
    enc = [i for i, c in enumerate(names) if c.startswith("table_")]
    c = rng.choice(acc)
    noise = float(np.median(np.abs(np.diff(data[:, c])))) or 1e-6
    if kind in ("spikes", "spike", "burst"):
        count = 1 if kind == "spike" else rng.randint(2, 30) if kind == "spikes" else 1
        width = rng.randint(2, 5) if kind == "burst" else 1
        size = rng.choice([10.0, 30.0, 100.0, 1000.0]) * noise * rng.choice([-1.0, 1.0])
        for _ in range(count):
            i = rng.randrange(n - width)
            data[i : i + width, c] += size
        desc = f"{count} x {width}-sample spike(s) of {size:.3g} on {names[c]}"
    elif kind == "clip":
        lo, hi = np.percentile(data[:, c], [1, 99])
        frac = rng.choice([0.3, 0.6, 0.9])
        rail = hi - frac * (hi - lo) / 2 if rng.random() < 0.5 else None
        if rail is not None:
            data[:, c] = np.minimum(data[:, c], rail)
            desc = f"{names[c]} clipped at {rail:.4g} (upper rail)"
        else:
            rail = lo + frac * (hi - lo) / 2
            data[:, c] = np.maximum(data[:, c], rail)
            desc = f"{names[c]} clipped at {rail:.4g} (lower rail)"
    elif kind == "encoder_round":
        q = rng.choice([0.05, 0.1, 0.25, 0.5, 1.0])
        data[:, enc] = np.round(data[:, enc] / q) * q
        desc = f"table angles rounded to {q:g} deg"
    elif kind == "encoder_lag":
        lag = rng.choice([2, 5, 10, 20, 40])
        data[lag:, enc] = data[:-lag, enc].copy()
        desc = f"encoders lag the DAQ by {lag} samples"
    elif kind == "channel_scale":
        f = rng.choice([1e3, 1e6, -1e6, 1e-6])
        data[:, c] *= f
        desc = f"{names[c]} multiplied by {f:g}"
    else:
        data[:, c] *= -1.0
        desc = f"{names[c]} sign flipped"
    return _csv(names, data), f"{kind}: {desc}"


def _set(obj: dict[str, Any], path: list[str | int], value: Any) -> None:
    d: Any = obj
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value


def _paths(obj: Any, prefix: list[str | int]) -> list[list[str | int]]:
    out = [prefix] if prefix else []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, [*prefix, k])
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _paths(v, [*prefix, i])
    return out


def mutate_sidecar(side: dict[str, Any], rng: random.Random) -> tuple[str | None, str]:
    """One mutation of the sidecar; returns (new JSON text or None for no sidecar, description)."""
    side = json.loads(json.dumps(side))
    kind = rng.choice(
        ["value", "value", "value", "delete", "deep", "truncate", "dup", "missing", "rate", "unit", "raw"]
    )
    paths = _paths(side, [])
    p = rng.choice(paths)
    if kind == "value":
        v = rng.choice(WEIRD_JSON)
        _set(side, p, v)
        return json.dumps(side), f"{p} = {str(v)[:20]!r}"
    if kind == "delete":
        d: Any = side
        for k in p[:-1]:
            d = d[k]
        del d[p[-1]]
        return json.dumps(side), f"delete {p}"
    if kind == "deep":
        n = rng.choice([40, 1000, 100_000])
        text = json.dumps(side)
        return text[:-1] + ', "x": ' + "[" * n + "]" * n + "}", f"nested {n} deep"
    if kind == "truncate":
        text = json.dumps(side)
        cut = rng.randrange(len(text))
        return text[:cut], f"truncate at {cut}"
    if kind == "dup":
        return json.dumps(side)[:-1] + ', "channel_unit": "g"}', "duplicate channel_unit"
    if kind == "missing":
        return None, "no sidecar"
    if kind == "rate":
        f = rng.choice([1e-300, 1e300, 0.5, 2.0, 1.1, 10.0])
        side["sample_rate_hz"] = side["sample_rate_hz"] * f
        return json.dumps(side), f"sample_rate_hz x{f:g}"
    if kind == "unit":
        side["channel_unit"] = rng.choice(["g", "m/s2", "count", "mV", ""])
        return json.dumps(side), f"channel_unit {side['channel_unit']!r}"
    literal = rng.choice(["NaN", "Infinity", "1e999", "9" * 400, "-0"])
    text = json.dumps(side).replace(json.dumps(side["g_local_m_s2"]), literal, 1)
    return text, f"g_local_m_s2 literal {literal}"


# ---- worker: calbench imported once --------------------------------------------------------


def _worker(conn: Connection) -> None:
    from api.cli import main as cli_main

    while True:
        job = conn.recv()
        if job is None:
            return
        out, err = io.StringIO(), io.StringIO()
        code: Any
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = cli_main(job)
            except SystemExit as exc:  # argparse
                code = exc.code
            except BaseException:
                code = "traceback"
                err.write(traceback.format_exc())
        conn.send((code, out.getvalue(), err.getvalue()))


class Worker:
    """A process running ``api.cli.main`` on request, restarted after a hang."""

    def __init__(self) -> None:
        # one BLAS thread: the commands' matrices are small, and on a shared machine a BLAS
        # thread pool spends CPU time waiting (docs/benchmarks.md), which the limit would count
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
        self._start()

    def _start(self) -> None:
        ctx = mp.get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child,), daemon=True)
        self.proc.start()

    def cpu_s(self) -> float | None:
        """The worker's CPU time so far (s, user + system, every thread), ``None`` without /proc."""
        try:
            fields = Path(f"/proc/{self.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            return None
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def run(self, argv: list[str], timeout_s: float = TIMEOUT_S) -> tuple[Any, str, str]:
        """(exit code or "traceback"/"hang", stdout, stderr) of ``calbench argv``; a hang is more
        than ``timeout_s`` of CPU time (:data:`TIMEOUT_S`) or :data:`WALL_LIMIT_S` of wall time."""
        cpu0, t0 = self.cpu_s(), time.perf_counter()
        self.conn.send(argv)
        while not self.conn.poll(1.0):
            cpu = self.cpu_s()
            wall = time.perf_counter() - t0
            used = wall if cpu is None or cpu0 is None else cpu - cpu0
            if used > timeout_s or wall > WALL_LIMIT_S:
                self.proc.kill()
                self.proc.join()
                self._start()
                return "hang", "", f"{used:.0f} s of CPU, {wall:.0f} s of wall time"
        try:
            return self.conn.recv()  # type: ignore[no-any-return]
        except EOFError:  # the worker died (a crash is a traceback too)
            self.proc.join()
            self._start()
            return "traceback", "", f"worker died with {self.proc.exitcode}"

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.conn.send(None)
        self.proc.join(5)


def _moved(base: dict[str, Any], got: dict[str, Any]) -> float:
    """Largest change of bias or K in units of the larger of the two sigmas."""
    z = 0.0
    for v, s in (("bias", "bias_sigma"), ("scale_matrix", "scale_matrix_sigma")):
        a, b = np.asarray(base[v], float), np.asarray(got[v], float)
        sa, sb = np.asarray(base[s], float), np.asarray(got[s], float)
        if a.shape != b.shape:
            return np.inf
        sig = np.maximum(sa, sb)
        with np.errstate(divide="ignore", invalid="ignore"):
            zz = np.abs(a - b) / sig
        z = max(z, float(np.nanmax(np.where(sig > 0, zz, np.inf))))
    return z


def _residual_grew(base: dict[str, Any], got: dict[str, Any]) -> bool:
    def ratio(key: str) -> float:
        b, g = base.get(key), got.get(key)
        return g / b if isinstance(b, int | float) and isinstance(g, int | float) and b > 0 else 1.0

    return max(ratio("chi2_dof"), ratio("residual_rms")) > RESIDUAL_GROWTH


def classify(
    cmd: str,
    code: Any,
    out: str,
    err: str,
    base: dict[str, Any] | None,
    equivalent: bool = False,
    json_warnings: bool = False,
) -> tuple[str, str]:
    """(class, detail) of one outcome, see the module docstring.

    :param json_warnings: a warning counts only when it is in the result's ``warnings`` (not
        stderr alone)."""
    if code in ("traceback", "hang"):
        return code, err.strip().splitlines()[-1] if err.strip() else ""
    if code == 2:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        if len(lines) != 1 or not lines[0].startswith(f"calbench {cmd}: "):
            return "exit2 multi-line", " | ".join(lines)[:300]
        return "exit2", lines[0][:200]
    if code != 0:
        return f"exit {code}", err[-300:]
    warned = "warning" in err
    if cmd != "calibrate" or base is None:
        return ("ok, flagged" if warned else "ok"), ""
    got = json.loads(out)
    if json_warnings:
        warned = bool(got.get("warnings"))
    z = _moved(base, got)
    if z > SIGMA_LIMIT and not warned and not _residual_grew(base, got):
        detail = f"moved {z:.1f} sigma, residual rms {got.get('residual_rms')}"
        return ("moved, equivalent" if equivalent else "silent"), detail
    return ("ok, flagged" if (warned or _residual_grew(base, got)) else "ok"), f"{z:.1f} sigma"


def run(
    n_mutants: int = 800,
    seed: int = 13,
    log: Callable[[str], None] = print,
    moving: bool = False,
    progress: bool = False,
    deadline_s: float | None = None,
    first: int = 0,
) -> Counter[str]:
    """Fuzz both commands with ``n_mutants`` mutants; returns the count of each class.

    :param moving: mutants of a rate-1axis recording (:func:`mutate_moving`), judged by the
        JSON's ``warnings``; else of a static-12 one.
    :param progress: log each mutant's classes and the commands' wall times as it finishes.
    :param deadline_s: stop after the mutant that passes this wall time (s) and report the
        mutants done (the same mutants as a full run's first ones: the draws do not depend on it).
    :param first: run the mutants from this one on (the ones before are drawn, not run), so that
        two processes can share one seed's mutants."""
    rng = random.Random(seed)
    worker = Worker()
    counts: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    try:
        with tempfile.TemporaryDirectory(prefix="calbench-fuzz-") as d:
            base_csv = Path(d) / "base.csv"
            simulate = ["simulate", "-o", str(base_csv), "--sample-rate-hz", "50", "--seed", "7"]
            if moving:
                simulate += ["--procedure", "rate-1axis"]
            else:
                simulate += ["--dwell-s", "3"]
            code, _, err = worker.run(simulate)
            assert code == 0, err
            csv_text = base_csv.read_text()
            side = json.loads(base_csv.with_suffix(".json").read_text())
            code, out, err = worker.run(["calibrate", "--json", str(base_csv)])
            assert code == 0, err
            base = json.loads(out)
            assert base["warnings"] == [], base["warnings"]
            t0 = time.perf_counter()
            done = 0
            for i in range(n_mutants):
                path = Path(d) / f"m{i:04d}.csv"
                if moving and rng.random() < 0.85:
                    text, desc = mutate_moving(csv_text, rng)
                    side_text: str | None = json.dumps(side)
                    label = desc.split(":")[0]
                elif not moving and rng.random() < 0.55:
                    text, desc = mutate_csv(csv_text, rng)
                    side_text = json.dumps(side)
                    label = "csv"
                else:
                    text, desc = csv_text, ""
                    side_text, desc = mutate_sidecar(side, rng)
                    label = "sidecar"
                if i < first:  # drawn, so that mutant i is the same as in a run from 0
                    continue
                path.write_bytes(text.encode("utf-8", "surrogateescape"))
                if side_text is not None:
                    path.with_suffix(".json").write_text(side_text, encoding="utf-8")
                classes = []
                for cmd in ("calibrate", "diagnose"):
                    t_cmd = time.perf_counter()
                    c, o, e = worker.run([cmd, "--json", str(path)])
                    cls, detail = classify(
                        cmd, c, o, e, base, equivalent=EQUIVALENT in desc, json_warnings=moving
                    )
                    counts[cls] += 1
                    classes.append(f"{cmd} {cls} ({time.perf_counter() - t_cmd:.0f} s)")
                    if moving and cmd == "calibrate":
                        kinds[f"{label}: {cls}"] += 1
                    if cls == "moved, equivalent":
                        log(f"  equivalent: mutant {i} ({desc}) {cmd}: {detail}")
                    if cls in ("traceback", "hang", "exit2 multi-line", "silent") or cls.startswith("exit "):
                        log(f"  BUG {cls}: mutant {i} ({desc}) {cmd}: {detail}")
                path.unlink()
                path.with_suffix(".json").unlink(missing_ok=True)
                done += 1
                if progress:
                    log(f"  mutant {i} ({label}): {', '.join(classes)}")
                if deadline_s is not None and time.perf_counter() - t0 > deadline_s:
                    break
            elapsed = time.perf_counter() - t0
    finally:
        worker.close()
    what = "moving (rate-1axis)" if moving else "static-12"
    asked = n_mutants - first
    stopped = f" (stopped at the {deadline_s:.0f} s limit; {asked} asked)" if done < asked else ""
    which = f", mutants {first}-{first + done - 1}" if first else ""
    log(f"{done} {what} mutants x 2 commands in {elapsed:.0f} s (seed {seed}{which}){stopped}:")
    for cls, n in sorted(counts.items()):
        log(f"  {cls:<18}{n:>6}")
    if kinds:
        log("calibrate, by fault:")
        for cls, n in sorted(kinds.items()):
            log(f"  {cls:<32}{n:>6}")
    return counts


BUGS = ("traceback", "hang", "exit2 multi-line", "silent")


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    moving = "--moving" in args
    progress = "--progress" in args
    deadline_s = next((float(a.split("=", 1)[1]) for a in args if a.startswith("--deadline-s=")), None)
    first = next((int(a.split("=", 1)[1]) for a in args if a.startswith("--first=")), 0)
    args = [a for a in args if not a.startswith("--")]
    n = int(args[0]) if args else 800
    seed = int(args[1]) if len(args) > 1 else 13
    counts = run(n, seed, moving=moving, progress=progress, deadline_s=deadline_s, first=first)
    bugs = sum(n for cls, n in counts.items() if cls in BUGS or cls.startswith("exit "))
    print(f"bugs: {bugs}")
    return 1 if bugs else 0


if __name__ == "__main__":
    sys.exit(main())
