"""How every error leaves the service: as JSON, with a 4xx or 507 status and a clear detail.

:func:`install_error_handlers` makes

- a validation error a 422 whose inputs are serialised by :func:`json_safe`: a ``NaN`` or
  ``Infinity`` (which JSON cannot carry) as its text;
- a database data error (a value the database cannot store, e.g. a NUL byte on PostgreSQL, an
  integer out of range) a 422 instead of a 500;
- a write refused because the server's disk is full (:func:`station.disk_full.is_disk_full`,
  a database ``OperationalError`` or an ``OSError``) a 507 saying nothing was stored, logged at
  most once per :data:`station.disk_full.DISK_FULL_LOG_INTERVAL_S`; any other such error
  stays the server's error.
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import DataError, OperationalError

from station.disk_full import DISK_FULL_LOG_INTERVAL_S, is_disk_full

log = logging.getLogger(__name__)


def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float replaced by its text (``"nan"``, ``"inf"``) and bytes
    decoded, recursively, so that strict JSON can carry it."""
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if value is None or isinstance(value, str | int | float | bool):
        return value
    return str(value)


async def _validation_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    return JSONResponse(status_code=422, content={"detail": json_safe(list(exc.errors()))})


async def _data_error(request: Request, exc: Exception) -> JSONResponse:
    orig = getattr(exc, "orig", None)
    reason = str(orig if orig is not None else exc).splitlines()[0][:200]
    log.info("database refused a value on %s %s: %s", request.method, request.url.path, reason)
    return JSONResponse(status_code=422, content={"detail": f"a value the database cannot store: {reason}"})


_disk_full_logged = [-math.inf]


async def _operational_error(request: Request, exc: Exception) -> JSONResponse:
    if not is_disk_full(exc):
        raise exc
    return _disk_full(request, exc)


async def _os_error(request: Request, exc: Exception) -> JSONResponse:
    if not is_disk_full(exc):
        raise exc
    return _disk_full(request, exc)


def _disk_full(request: Request, exc: Exception) -> JSONResponse:
    now = time.monotonic()
    if now - _disk_full_logged[0] >= DISK_FULL_LOG_INTERVAL_S:
        _disk_full_logged[0] = now
        reason = str(getattr(exc, "orig", None) or exc).splitlines()[0][:200]
        log.error("disk full: %s %s refused (%s); further refusals are not logged for %g s",
                  request.method, request.url.path, reason, DISK_FULL_LOG_INTERVAL_S)  # fmt: skip
    return JSONResponse(
        status_code=507,
        content={
            "detail": "the server's disk is full: nothing was stored; free space and send the request again"
        },
    )


def install_error_handlers(app: FastAPI) -> None:
    """Validation errors serialised without non-finite numbers; database data errors as 422; a
    write refused because the disk is full as 507 with a clear message, logged once a minute."""
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(DataError, _data_error)
    app.add_exception_handler(OperationalError, _operational_error)
    app.add_exception_handler(OSError, _os_error)
