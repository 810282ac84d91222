"""Portable enum column: a VARCHAR with a named CHECK constraint, storing the enum's values."""

from __future__ import annotations

import enum

import sqlalchemy as sa


def value_enum(enum_cls: type[enum.Enum], name: str, length: int = 16) -> sa.Enum:
    """A non-native ``sa.Enum`` storing ``member.value`` (same on SQLite and PostgreSQL)."""
    return sa.Enum(
        enum_cls,
        name=name,
        native_enum=False,
        create_constraint=True,
        length=length,
        validate_strings=True,
        values_callable=lambda cls: [m.value for m in cls],
    )
