"""The benchmark's readers (``benchmarks/load_readers.py``) against a scripted HTTP/1.1 server:
they send back the ETag they were given, count 200 and 304 answers, read ``Content-Length`` and
chunked bodies, and follow an event stream to its ``finished`` event."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from benchmarks.load_readers import run

pytestmark = pytest.mark.timeout(30)
TAG = '"abc"'


async def _serve(
    reader: asyncio.StreamReader, writer: asyncio.StreamWriter, seen: list[dict[str, str]]
) -> None:
    """Answers ``/doc`` with a tagged body (304 when the tag comes back), ``/events`` with a chunked
    stream of two progress events and a finished one."""
    try:
        while True:
            head = (await reader.readuntil(b"\r\n\r\n")).decode("latin-1").split("\r\n")
            path = head[0].split(" ")[1]
            headers = {k.lower(): v.strip() for k, _, v in (h.partition(":") for h in head[1:] if h)}
            seen.append({"path": path, **headers})
            if path == "/events":
                writer.write(b"HTTP/1.1 200 OK\r\ntransfer-encoding: chunked\r\n\r\n")
                for event in (b"progress", b"progress", b"finished"):
                    data = b"event: " + event + b"\ndata: {}\n\n"
                    writer.write(f"{len(data):x}\r\n".encode() + data + b"\r\n")
                writer.write(b"0\r\n\r\n")
            elif headers.get("if-none-match") == TAG:
                writer.write(f"HTTP/1.1 304 Not Modified\r\netag: {TAG}\r\n\r\n".encode())
            else:
                body = b'{"doc": 1}'
                writer.write(
                    f"HTTP/1.1 200 OK\r\netag: {TAG}\r\ncontent-length: {len(body)}\r\n\r\n".encode() + body
                )
            await writer.drain()
    except (asyncio.IncompleteReadError, ConnectionError):
        pass
    finally:
        writer.close()


def test_readers_revalidate_and_followers_count_events() -> None:
    seen: list[dict[str, str]] = []

    async def main() -> dict[str, Any]:
        server = await asyncio.start_server(lambda r, w: _serve(r, w, seen), "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        async with server:
            return await run(
                {
                    "host": "127.0.0.1",
                    "port": port,
                    "token": "viewer-token-0001",
                    "readers": 2,
                    "cycles": 3,
                    "duration_s": 10.0,
                    "pause_s": 0.0,
                    "page_every": 2,
                    "page": [["page", "/doc?page"]],
                    "poll": [["doc", "/doc"]],
                    "followers": 2,
                    "events": "/events",
                }
            )

    out = asyncio.run(main())
    # per reader: cycle 0 page + doc, cycle 1 doc, cycle 2 page + doc = 3 doc, 2 page requests;
    # the first of each path is a 200, every later one carries its tag and is a 304
    assert {k: len(v) for k, v in out["latency_s"].items()} == {"doc": 6, "page": 4}
    assert out["status"] == {"200": 4, "304": 6}
    assert out["errors"] == []
    assert out["events"] == {"progress": 4, "finished": 2}
    docs = [h for h in seen if h["path"] != "/events"]
    assert all(h["authorization"] == "Bearer viewer-token-0001" for h in seen)
    assert sum("if-none-match" in h for h in docs) == 6
    assert out["cpu_s"] > 0.0
