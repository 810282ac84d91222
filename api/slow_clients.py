"""A deadline on a request's header phase, so a client that sends its headers slowly (a
"slowloris") cannot hold a connection of the service for ever.

uvicorn's ``timeout_keep_alive`` closes a connection only while no byte comes; a client
that sends one header byte every few seconds keeps it open indefinitely, and h11 has no
deadline of its own. :class:`HeaderDeadlineH11Protocol` (uvicorn's h11 protocol, the one the
service uses) gives every request :data:`HEADER_READ_TIMEOUT_S` from its first byte (or from
the connection's opening) to complete its request line and headers; past that it answers
``408 Request Timeout`` and closes the connection. A body that stalls is the body's deadline
(:data:`api.guard.BODY_READ_TIMEOUT_S`).

``calbench serve`` passes it to uvicorn as ``http=`` :data:`PROTOCOL`.
"""

from __future__ import annotations

import asyncio
import logging

from uvicorn.protocols.http.h11_impl import H11Protocol

log = logging.getLogger(__name__)

HEADER_READ_TIMEOUT_S = 10.0
"""Longest time a client has to send a request line and its headers (s)."""
PROTOCOL = "api.slow_clients:HeaderDeadlineH11Protocol"
"""Import path of the protocol class, for ``uvicorn.run(http=...)`` and ``uvicorn.Config``."""

_TIMEOUT_RESPONSE = (
    b"HTTP/1.1 408 Request Timeout\r\n"
    b"content-type: text/plain; charset=utf-8\r\n"
    b"connection: close\r\n"
    b"content-length: 38\r\n\r\n"
    b"request headers not received in time\r\n"
)


class HeaderDeadlineH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with a deadline of :attr:`header_timeout_s` on each request's
    headers: armed when the connection opens and when the first byte of a next request comes,
    disarmed once the request's headers are complete (uvicorn has started its cycle)."""

    header_timeout_s = HEADER_READ_TIMEOUT_S
    _header_timer: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._arm()

    def data_received(self, data: bytes) -> None:
        if self._header_timer is None and self._between_requests():
            self._arm()
        super().data_received(data)
        if self._header_timer is not None and not self._between_requests():
            self._disarm()  # the headers are in: the request is being served

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def _between_requests(self) -> bool:
        return self.cycle is None or self.cycle.response_complete

    def _arm(self) -> None:
        self._disarm()
        self._header_timer = self.loop.call_later(self.header_timeout_s, self._headers_timed_out)

    def _disarm(self) -> None:
        if self._header_timer is not None:
            self._header_timer.cancel()
            self._header_timer = None

    def _headers_timed_out(self) -> None:
        self._header_timer = None
        if self.transport.is_closing() or not self._between_requests():
            return
        client = f"{self.client[0]}:{self.client[1]}" if self.client else "a client"
        log.info("%s: request headers not complete in %g s; closed", client, self.header_timeout_s)
        self.transport.write(_TIMEOUT_RESPONSE)
        self.transport.close()
