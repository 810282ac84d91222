"""Declarative base of every calbench table.

A naming convention gives every index and constraint a stable name, which Alembic's
batch mode needs to alter SQLite tables and which keeps autogenerate diffs empty on both
dialects. ``type_annotation_map`` maps ``datetime`` to :class:`db.types.UtcDateTime` and
``dict``/``list`` to portable JSON (:class:`db.types.TolerantJSON`: a stored value that is
not JSON loads as an unreadable marker instead of failing the query), so models use
``Mapped[...]`` annotations only.
"""

from __future__ import annotations

import datetime as dt
from typing import Any, ClassVar

import sqlalchemy as sa
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

from db.types import TolerantJSON, UtcDateTime, utc_now

NAMING_CONVENTION: dict[str, str] = {
    "ix": "ix_%(table_name)s__%(column_0_N_name)s",
    "uq": "uq_%(table_name)s__%(column_0_N_name)s",
    "ck": "ck_%(table_name)s__%(constraint_name)s",
    "fk": "fk_%(table_name)s__%(column_0_name)s__%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class Base(DeclarativeBase):
    """Base class: naming convention, type map and a ``created_at`` (UTC) on every table."""

    metadata = sa.MetaData(naming_convention=NAMING_CONVENTION)
    type_annotation_map: ClassVar[dict[Any, Any]] = {
        dt.datetime: UtcDateTime(),
        dict[str, Any]: TolerantJSON(),
        list[Any]: TolerantJSON(array=True),
    }

    created_at: Mapped[dt.datetime] = mapped_column(
        default=utc_now, server_default=sa.func.current_timestamp()
    )


class IntId:
    """Mixin: an autoincrement integer primary key ``id``."""

    id: Mapped[int] = mapped_column(sa.Integer, primary_key=True, autoincrement=True, sort_order=-1)
