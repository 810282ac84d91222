"""Portable column types: timezone-aware UTC timestamps, JSON and numpy arrays as ``.npy`` bytes.

Portability lives here, not in ``if dialect`` branches across the code (the Prefect
``Timestamp`` pattern): every timestamp in the database is UTC, and a naive ``datetime``
is refused at bind time because its meaning (local? UTC?) cannot be known.

A stored value that cannot be parsed (JSON text that is not JSON, a timestamp that is not a
time: a row written by another tool, or a damaged database) does not fail the query that
reads it, which would take every row of the page down with it: it loads as an unreadable
marker (:class:`UnreadableDict`, :class:`UnreadableList`, :class:`UnreadableTime`) that
behaves as an empty value and carries the parser's message (:func:`unreadable_reason`).
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


class UnreadableDict(dict[str, Any]):
    """A stored JSON object that could not be parsed: empty, with the parser's message in ``error``."""

    def __init__(self, error: str) -> None:
        super().__init__()
        self.error = error


class UnreadableList(list[Any]):
    """A stored JSON array that could not be parsed: empty, with the parser's message in ``error``."""

    def __init__(self, error: str) -> None:
        super().__init__()
        self.error = error


class UnreadableTime(dt.datetime):
    """A stored timestamp that could not be parsed: 0001-01-01 UTC (it sorts first), with the
    parser's message in ``error``."""

    error: str

    @classmethod
    def of(cls, error: str) -> UnreadableTime:
        """The marker for one unparsable value."""
        t = cls(1, 1, 1, tzinfo=UTC)
        t.error = error
        return t


def unreadable_reason(value: object) -> str | None:
    """The parser's message when ``value`` is an unreadable marker, else ``None``."""
    if isinstance(value, UnreadableDict | UnreadableList | UnreadableTime):
        return value.error
    return None


def _shown(raw: object, n: int = 40) -> str:
    text = raw if isinstance(raw, str) else repr(raw)
    return repr(text if len(text) <= n else text[:n] + "…")


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

    def result_processor(self, dialect: Dialect, coltype: Any) -> Any:
        inner = super().result_processor(dialect, coltype)
        if inner is None:
            return None

        def process(value: Any) -> dt.datetime | None:
            try:
                parsed: dt.datetime | None = inner(value)  # SQLAlchemy types the processor's result Any
                return parsed
            except (ValueError, TypeError, OverflowError) as exc:
                return UnreadableTime.of(f"not a time: {_shown(value)} ({exc})")

        return process

    def process_result_value(self, value: dt.datetime | None, dialect: Dialect) -> dt.datetime | None:
        if value is None or isinstance(value, UnreadableTime):
            return value
        if value.tzinfo is None:
            return value.replace(tzinfo=UTC)
        return value.astimezone(UTC)


class TolerantJSON(TypeDecorator[Any]):
    """JSON (``sa.JSON``); stored text that is not JSON loads as :class:`UnreadableDict` (or
    :class:`UnreadableList` for a column of arrays) naming the parser's message.

    :param array: the column holds arrays (``list``) rather than objects.
    """

    impl = sa.JSON
    cache_ok = True

    def __init__(self, array: bool = False) -> None:
        super().__init__()
        self.array = array

    def result_processor(self, dialect: Dialect, coltype: Any) -> Any:
        inner = super().result_processor(dialect, coltype)
        array = self.array

        def process(value: Any) -> Any:
            try:
                return inner(value) if inner is not None else value
            except ValueError as exc:
                error = f"not JSON: {_shown(value)} ({exc})"
                return UnreadableList(error) if array else UnreadableDict(error)

        return process


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
        # process_bind_param writes one .npy file, so np.load gives an ndarray (not an NpzFile).
        arr: npt.NDArray[Any] = np.load(io.BytesIO(bytes(value)), allow_pickle=False)
        return arr

    def compare_values(self, x: Any, y: Any) -> bool:
        if x is None or y is None:
            return x is y
        a, b = np.asarray(x), np.asarray(y)
        return a.shape == b.shape and a.dtype == b.dtype and bool(np.array_equal(a, b, equal_nan=True))
