"""Portable column types: timezone-aware UTC timestamps and numpy arrays as ``.npy`` bytes.

Portability lives here, not in ``if dialect`` branches across the code (the Prefect
``Timestamp`` pattern): every timestamp in the database is UTC, and a naive ``datetime``
is refused at bind time because its meaning (local? UTC?) cannot be known.
"""

from __future__ import annotations

import datetime as dt
import io
from typing import Any

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa
from sqlalchemy.engine import Dialect
from sqlalchemy.types import TypeDecorator

UTC = dt.UTC


def utc_now() -> dt.datetime:
    """The current time as an aware UTC ``datetime``."""
    return dt.datetime.now(UTC)


class UtcDateTime(TypeDecorator[dt.datetime]):
    """Aware UTC ``datetime``; naive values are rejected with ``ValueError``.

    PostgreSQL stores ``timestamp with time zone``; SQLite stores the UTC wall time as
    text and the zone is re-attached on load. Values come back as UTC on both.
    """

    impl = sa.DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: dt.datetime | None, dialect: Dialect) -> dt.datetime | None:
        if value is None:
            return None
        if not isinstance(value, dt.datetime):
            raise TypeError(f"UtcDateTime expects a datetime, got {type(value).__name__}")
        if value.tzinfo is None or value.utcoffset() is None:
            raise ValueError(f"naive datetime {value.isoformat()} refused: timestamps must carry a time zone")
        value = value.astimezone(UTC)
        if dialect.name == "sqlite":
            return value.replace(tzinfo=None)
        return value

    def process_result_value(self, value: dt.datetime | None, dialect: Dialect) -> dt.datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            return value.replace(tzinfo=UTC)
        return value.astimezone(UTC)


class NpyArray(TypeDecorator[npt.NDArray[Any]]):
    """A numpy array stored as the bytes of one ``.npy`` file (``numpy.save``).

    Shape and dtype survive the round trip; object arrays (pickles) are refused both ways.
    """

    impl = sa.LargeBinary
    cache_ok = True

    def process_bind_param(self, value: npt.ArrayLike | None, dialect: Dialect) -> bytes | None:
        if value is None:
            return None
        arr = np.asarray(value)
        if arr.dtype == object:
            raise ValueError("NpyArray refuses object arrays: store numeric arrays only")
        buf = io.BytesIO()
        np.save(buf, arr, allow_pickle=False)
        return buf.getvalue()

    def process_result_value(self, value: bytes | None, dialect: Dialect) -> npt.NDArray[Any] | None:
        if value is None:
            return None
        return np.load(io.BytesIO(bytes(value)), allow_pickle=False)

    def compare_values(self, x: Any, y: Any) -> bool:
        if x is None or y is None:
            return x is y
        a, b = np.asarray(x), np.asarray(y)
        return a.shape == b.shape and a.dtype == b.dtype and bool(np.array_equal(a, b, equal_nan=True))
