"""What every request passes before a route sees it.

:class:`RequestGuard` (pure ASGI, outermost) refuses, before one byte of a body is read:

- a URL with a NUL byte (400) or longer than :data:`MAX_URL_CHARS` (414);
- a body larger than its limit (413): :data:`MAX_JSON_BODY_BYTES` for JSON requests,
  :data:`MAX_UPLOAD_BODY_BYTES` for the recording upload; by ``Content-Length`` when it is
  sent, else by counting as the body streams in;
- a request that carries a body (``POST``, ``PUT``, ``PATCH``, ``DELETE``) to ``/api/``
  without a token of the role every such endpoint needs (401/403): operator, or viewer for
  ``POST /api/links``. So an unauthenticated client can make the service neither read
  nor store anything. The route still checks its own role.

- a client (by address) that presented too many unknown tokens or bad links (answers 401)
  within a while: every request of it that carries a credential is answered 429 with
  ``Retry-After`` (:class:`api.failed_auth.FailedAuthLimiter`), so secrets cannot be guessed
  at the rate the service answers;
- a body that stalls: no part of it for :data:`BODY_READ_TIMEOUT_S` (408; a slow client cannot
  hold a worker with a request it never finishes);

parses a JSON body once under the size rules of :mod:`bench.inputs` (nesting, integer digits,
duplicate keys: **422** naming the rule) and hands it on, and adds the security headers to
every response (:data:`SECURITY_HEADERS`, and `X-Calbench-Worker`: which API process answered):
a Content-Security-Policy that allows scripts and
connections only from the service itself and no framing, ``X-Frame-Options: DENY``,
``nosniff`` and no referrer.

How an error a route raises leaves is :mod:`api.error_handlers`; credentials are kept out of
the access log by :mod:`api.log_redaction`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Awaitable, Callable, MutableMapping
from typing import Any

import anyio
import anyio.to_thread

from api.auth import AuthError, Role
from api.failed_auth import FailedAuthLimiter
from bench.inputs import InputError, loads_json

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

MAX_URL_CHARS = 4096
MAX_JSON_BODY_BYTES = 1024 * 1024
"""Largest JSON request body (bytes); the largest real one (a unit registration) is under 2 kB."""
UPLOAD_PATHS = frozenset({"/api/recordings"})
MAX_UPLOAD_BODY_BYTES = 2 * 512 * 1024 * 1024 + 1024 * 1024
"""Largest multipart upload (bytes): two files of 512 MB each (CSV and sidecar) and the form's own bytes."""
BODY_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})
VIEWER_BODY_PATHS = frozenset({"/api/links"})
"""Body-carrying endpoints a viewer may call; every other one needs an operator."""

_CSP_APP = (
    "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; "
    "connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'"
)
_CSP_DOCS = (
    "default-src 'self'; script-src 'self' 'unsafe-inline' https://cdn.jsdelivr.net; "
    "style-src 'self' 'unsafe-inline' https://cdn.jsdelivr.net; img-src 'self' data: https:; "
    "connect-src 'self'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'"
)
DOCS_PATHS = frozenset({"/docs", "/redoc", "/docs/oauth2-redirect"})
SECURITY_HEADERS: dict[str, str] = {
    "content-security-policy": _CSP_APP,
    "x-frame-options": "DENY",
    "x-content-type-options": "nosniff",
    "referrer-policy": "no-referrer",
}
BODY_READ_TIMEOUT_S = 30.0
"""Longest wait for the next part of a request body (s)."""


class _TooLarge(Exception):
    pass


class _Stalled(Exception):
    pass


def _is_json(scope: Scope) -> bool:
    media = _headers(scope).get("content-type", "").split(";")[0].strip().lower()
    return media == "application/json" or media.endswith("+json")


def _json_problem(body: bytes) -> str | None:
    """Why a JSON body breaks the size rules of :mod:`bench.inputs` (nesting, integer digits,
    duplicate keys), or ``None``. Text that is not JSON at all is left to the app's own 422;
    non-finite numbers to the models, which name the field."""
    try:
        loads_json(body.decode("utf-8"), finite=False)
    except InputError as exc:
        return str(exc)
    except ValueError:  # not UTF-8 or not JSON: FastAPI answers it
        return None
    return None


def _replay(body: bytes, receive: Receive) -> Receive:
    """A ``receive`` that hands the already-read body to the app, then the client's messages."""
    sent = False

    async def replay() -> Message:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()

    return replay


def _headers(scope: Scope) -> dict[str, str]:
    return {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}


def _bearer(headers: dict[str, str]) -> str | None:
    scheme, _, secret = headers.get("authorization", "").partition(" ")
    return secret.strip() or None if scheme.lower() == "bearer" else None


class RequestGuard:
    """ASGI middleware: URL and body-size limits, authentication before any body is read,
    security headers on every response (see the module docstring)."""

    def __init__(self, app: ASGIApp, limiter: FailedAuthLimiter | None = None) -> None:
        self.app = app
        self.limiter = limiter or FailedAuthLimiter()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        path: str = scope.get("path", "")
        headers_to_add = dict(SECURITY_HEADERS)
        if path in DOCS_PATHS:
            headers_to_add["content-security-policy"] = _CSP_DOCS
        services = getattr(scope["app"].state, "services", None) if "app" in scope else None
        if services is not None:  # which API process answered (calbench serve --workers N)
            headers_to_add["x-calbench-worker"] = services.worker_id
        started = refused = False
        client = str((scope.get("client") or ("?",))[0])
        presented = _presents_credential(scope)

        async def send_with_headers(message: Message) -> None:
            nonlocal started
            if refused:  # the 413 is out: what the app answers after it is dropped
                return
            if message["type"] == "http.response.start":
                started = True
                if message.get("status") == 401 and presented:  # a wrong guess, not a missing token
                    self.limiter.failed(client)
                present = {k.decode("latin-1").lower() for k, _ in message.get("headers", [])}
                extra = [(k.encode(), v.encode()) for k, v in headers_to_add.items() if k not in present]
                message["headers"] = [*message.get("headers", []), *extra]
            await send(message)

        wait_s = self.limiter.retry_after_s(client) if presented else None
        if wait_s is not None:
            detail = (
                f"too many failed authentications from {client}: {self.limiter.limit} within "
                f"{self.limiter.window_s:g} s; try again in {math.ceil(wait_s)} s"
            )
            await self._reply(send_with_headers, 429, detail, {"retry-after": str(math.ceil(wait_s))})
            return
        refusal = await self._refusal(scope, path)
        if refusal is not None:
            status, detail, extra_headers = refusal
            await self._reply(send_with_headers, status, detail, extra_headers)
            return
        limit = MAX_UPLOAD_BODY_BYTES if path in UPLOAD_PATHS else MAX_JSON_BODY_BYTES
        if scope.get("method") in BODY_METHODS and _is_json(scope):
            try:
                body = await self._read_json_body(receive, limit)
            except _Stalled:
                await self._reply(send_with_headers, 408, _stalled_detail(), {})
                return
            if body is None:
                await self._reply(send_with_headers, 413, f"request body larger than {limit} bytes", {})
                return
            problem = _json_problem(body)
            if problem is not None:
                invalid = [{"type": "json_invalid", "loc": ["body"], "msg": problem, "input": None}]
                await self._reply(send_with_headers, 422, invalid, {})
                return
            receive = _replay(body, receive)
        received = 0
        body_done = False

        async def counting_receive() -> Message:
            nonlocal received, refused, body_done
            if body_done:  # only the disconnect is left: a stream waits for it as long as it runs
                return await receive()
            try:
                message = await _receive_within(receive)
            except _Stalled:
                if not started:
                    await self._reply(send_with_headers, 408, _stalled_detail(), {})
                    refused = True
                raise
            if message["type"] == "http.request":
                body_done = not message.get("more_body", False)
                received += len(message.get("body", b""))
                if received > limit:
                    # answered here: the app (FastAPI) turns any error while reading into a 400
                    if not started:
                        await self._reply(
                            send_with_headers, 413, f"request body larger than {limit} bytes", {}
                        )
                        refused = True
                    raise _TooLarge
            return message

        try:
            await self.app(scope, counting_receive, send_with_headers)
        except (_TooLarge, _Stalled):
            if not refused:
                raise

    async def _refusal(self, scope: Scope, path: str) -> tuple[int, str, dict[str, str]] | None:
        raw_path = scope.get("raw_path") or path.encode("utf-8", "surrogateescape")
        query: bytes = scope.get("query_string", b"")
        if len(raw_path) + len(query) > MAX_URL_CHARS:
            return 414, f"URL longer than {MAX_URL_CHARS} characters", {}
        if "\x00" in path or b"%00" in query.lower() or b"%00" in raw_path.lower() or b"\x00" in query:
            return 400, "NUL byte in the URL", {}
        method = scope.get("method", "GET")
        if method not in BODY_METHODS:
            return None
        headers = _headers(scope)
        limit = MAX_UPLOAD_BODY_BYTES if path in UPLOAD_PATHS else MAX_JSON_BODY_BYTES
        length = headers.get("content-length")
        if length is not None:
            if not length.isascii() or not length.isdigit():
                return 400, "Content-Length is not a number", {}
            if len(length) > 15 or int(length) > limit:
                return 413, f"request body of {length} bytes; at most {limit} bytes here", {}
        if not path.startswith("/api/"):
            return None
        services = getattr(scope["app"].state, "services", None) if "app" in scope else None
        if services is None:
            return 503, "the service is starting or stopping", {}
        minimum = Role.VIEWER if path in VIEWER_BODY_PATHS else Role.OPERATOR
        secret = _bearer(headers)
        try:
            await anyio.to_thread.run_sync(services.auth.require_principal, secret, minimum)
        except AuthError as exc:
            extra = {"www-authenticate": "Bearer"} if exc.status_code == 401 else {}
            return exc.status_code, str(exc), extra
        return None

    @staticmethod
    async def _read_json_body(receive: Receive, limit: int) -> bytes | None:
        """The whole JSON body (at most ``limit`` bytes; ``None`` past it)."""
        chunks: list[bytes] = []
        size = 0
        while True:
            message = await _receive_within(receive)
            if message["type"] != "http.request":
                break
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > limit:
                return None
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        return b"".join(chunks)

    @staticmethod
    async def _reply(send: Send, status: int, detail: Any, headers: dict[str, str]) -> None:
        body = json.dumps({"detail": detail}).encode("utf-8")
        raw = [
            (b"content-type", b"application/json"),
            (b"content-length", str(len(body)).encode()),
            (b"connection", b"close"),
            *((k.encode(), v.encode()) for k, v in headers.items()),
        ]
        await send({"type": "http.response.start", "status": status, "headers": raw})
        await send({"type": "http.response.body", "body": body})


async def _receive_within(receive: Receive) -> Message:
    """The next message of the client, or :class:`_Stalled` after :data:`BODY_READ_TIMEOUT_S`."""
    with anyio.move_on_after(BODY_READ_TIMEOUT_S) as scope:
        return await receive()
    if scope.cancelled_caught:
        raise _Stalled
    raise _Stalled  # pragma: no cover - move_on_after either returns or cancels


def _stalled_detail() -> str:
    return f"request body stalled: nothing received for {BODY_READ_TIMEOUT_S:g} s"


def _presents_credential(scope: Scope) -> bool:
    """The request carries a token (``Authorization``) or a signed link (``?link=``)."""
    if any(k.lower() == b"authorization" for k, _ in scope.get("headers", [])):
        return True
    return b"link=" in scope.get("query_string", b"")
