"""The dashboard's readers of ``bench_api_load``, in a process of their own.

``python -m benchmarks.load_readers CONFIG.json OUT.json`` runs ``readers`` readers on one
asyncio loop, each on its own keep-alive HTTP/1.1 connection, for ``duration_s`` seconds (or
``cycles`` cycles each), and ``followers`` clients that follow a run's event stream to its end,
as the run page does. A reader fetches, one after the other and without pause when
``pause_s`` is 0, the paths of ``poll`` and, every ``page_every``-th cycle, those of ``page``
(what opening a page fetches once). Like the dashboard (``api/static/api.js``) it sends back the
``ETag`` of the last answer to the same path as ``If-None-Match``, and takes a 304 as that answer.

OUT.json gets the latencies (s, per request kind, time from the request's first byte sent to
the answer's last byte read), the count of 200 and 304 answers, the errors, the events the
followers saw and this process's own CPU time (user + system), so that the client's cost is
measured apart from the service's.

The client is a small HTTP/1.1 reader (status line, headers, ``Content-Length`` or chunked
body) rather than a general library, so that at a few hundred requests per second it costs
the shared machine little and adds little to the latency it measures.
"""

from __future__ import annotations

import asyncio
import json
import resource
import sys
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


class HttpError(Exception):
    """A malformed or closed answer, named."""


@dataclass
class Answer:
    """One HTTP answer: status, headers (lower-case names), body."""

    status: int
    headers: dict[str, str]
    body: bytes


async def _read_head(reader: asyncio.StreamReader) -> tuple[int, dict[str, str]]:
    head = await reader.readuntil(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    parts = lines[0].split(" ", 2)
    if len(parts) < 2 or not parts[0].startswith("HTTP/1."):
        raise HttpError(f"bad status line {lines[0]!r}")
    headers: dict[str, str] = {}
    for line in lines[1:]:
        if line:
            name, _, value = line.partition(":")
            headers[name.strip().lower()] = value.strip()
    return int(parts[1]), headers


async def _chunks(reader: asyncio.StreamReader) -> Any:
    """The chunks of a chunked body, as they arrive (an async generator of bytes)."""
    while True:
        size = int((await reader.readuntil(b"\r\n")).split(b";")[0], 16)
        if size == 0:
            await reader.readuntil(b"\r\n")
            return
        data = await reader.readexactly(size)
        await reader.readexactly(2)
        yield data


class Connection:
    """One keep-alive HTTP/1.1 connection to ``host:port`` sending ``auth`` on every request."""

    def __init__(self, host: str, port: int, auth: str) -> None:
        self.host, self.port, self.auth = host, port, auth
        self._streams: tuple[asyncio.StreamReader, asyncio.StreamWriter] | None = None

    async def _open(self) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
        if self._streams is None:
            self._streams = await asyncio.open_connection(self.host, self.port, limit=2**24)
        return self._streams

    def _request(self, path: str, extra: dict[str, str]) -> bytes:
        lines = [
            f"GET {path} HTTP/1.1",
            f"Host: {self.host}:{self.port}",
            f"Authorization: Bearer {self.auth}",
        ]
        lines += [f"{k}: {v}" for k, v in extra.items()]
        return ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1")

    async def get(self, path: str, extra: dict[str, str] | None = None) -> Answer:
        """GET ``path``; the whole body is read. A connection the server closed is reopened once."""
        for attempt in (0, 1):
            reader, writer = await self._open()
            try:
                writer.write(self._request(path, extra or {}))
                await writer.drain()
                status, headers = await _read_head(reader)
                break
            except (ConnectionError, asyncio.IncompleteReadError):
                self.close()
                if attempt:
                    raise
        if "content-length" in headers:
            body = await reader.readexactly(int(headers["content-length"]))
        elif headers.get("transfer-encoding", "").lower() == "chunked":
            body = b"".join([c async for c in _chunks(reader)])
        else:
            body = b""
        if headers.get("connection", "").lower() == "close":
            self.close()
        return Answer(status, headers, body)

    async def events(self, path: str) -> dict[str, int]:
        """Follow a server-sent event stream to its ``finished`` event; the events by name."""
        reader, writer = await self._open()
        writer.write(self._request(path, {"Accept": "text/event-stream"}))
        await writer.drain()
        status, _ = await _read_head(reader)
        if status != 200:
            raise HttpError(f"{path}: HTTP {status}")
        counts: dict[str, int] = defaultdict(int)
        buf = b""
        async for chunk in _chunks(reader):
            buf += chunk
            *lines, buf = buf.split(b"\n")
            for line in lines:
                if line.startswith(b"event:"):
                    name = line[6:].strip().decode()
                    counts[name] += 1
                    if name == "finished":
                        self.close()
                        return dict(counts)
        return dict(counts)

    def close(self) -> None:
        """Close the connection (the next request opens a new one)."""
        if self._streams is not None:
            self._streams[1].close()
            self._streams = None


@dataclass
class Tally:
    """What all the readers measured."""

    latency_s: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))
    status: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    errors: list[str] = field(default_factory=list)
    events: dict[str, int] = field(default_factory=lambda: defaultdict(int))


async def _reader(cfg: dict[str, Any], deadline: float, tally: Tally, start_delay_s: float) -> None:
    conn = Connection(cfg["host"], cfg["port"], cfg["token"])
    etags: dict[str, str] = {}
    n = 0
    await asyncio.sleep(start_delay_s)
    try:
        while time.monotonic() < deadline and (cfg.get("cycles") is None or n < cfg["cycles"]):
            t_cycle = time.monotonic()
            paths = [*cfg["page"], *cfg["poll"]] if n % cfg["page_every"] == 0 else cfg["poll"]
            for kind, path in paths:
                extra = {"If-None-Match": etags[path]} if path in etags else {}
                t0 = time.perf_counter()
                try:
                    ans = await conn.get(path, extra)
                except (OSError, HttpError, asyncio.IncompleteReadError, ValueError) as exc:
                    tally.errors.append(f"{kind}: {type(exc).__name__}")
                    conn.close()
                    continue
                tally.latency_s[kind].append(time.perf_counter() - t0)
                tally.status[str(ans.status)] += 1
                if ans.status == 200 and "etag" in ans.headers:
                    etags[path] = ans.headers["etag"]
                elif ans.status not in (200, 304):
                    tally.errors.append(f"{kind}: HTTP {ans.status}")
            n += 1
            await asyncio.sleep(max(0.0, cfg["pause_s"] - (time.monotonic() - t_cycle)))
    finally:
        conn.close()


async def _follower(cfg: dict[str, Any], tally: Tally) -> None:
    conn = Connection(cfg["host"], cfg["port"], cfg["token"])
    try:
        for name, k in (await conn.events(cfg["events"])).items():
            tally.events[name] += k
    except (OSError, HttpError, asyncio.IncompleteReadError, ValueError) as exc:
        tally.errors.append(f"events: {type(exc).__name__}")
    finally:
        conn.close()


async def run(cfg: dict[str, Any]) -> dict[str, Any]:
    """Run the readers and followers of ``cfg``; the tally as JSON-ready data."""
    tally = Tally()
    t0 = time.monotonic()
    deadline = t0 + float(cfg["duration_s"])
    spread = float(cfg.get("spread_s", 0.5))
    n = int(cfg["readers"])
    followers = [asyncio.create_task(_follower(cfg, tally)) for _ in range(int(cfg.get("followers", 0)))]
    await asyncio.gather(*(_reader(cfg, deadline, tally, spread * i / max(n, 1)) for i in range(n)))
    wall_s = time.monotonic() - t0
    if followers:
        await asyncio.wait(followers, timeout=float(cfg.get("followers_timeout_s", 600.0)))
        for task in followers:
            task.cancel()
    use = resource.getrusage(resource.RUSAGE_SELF)
    return {
        "wall_s": wall_s,
        "cpu_s": use.ru_utime + use.ru_stime,
        "latency_s": dict(tally.latency_s),
        "status": dict(tally.status),
        "errors": tally.errors,
        "events": dict(tally.events),
    }


def main(argv: list[str]) -> int:
    """``load_readers CONFIG.json OUT.json``."""
    if len(argv) != 2:
        print("usage: python -m benchmarks.load_readers CONFIG.json OUT.json", file=sys.stderr)
        return 2
    cfg = json.loads(Path(argv[0]).read_text())
    Path(argv[1]).write_text(json.dumps(asyncio.run(run(cfg))))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
