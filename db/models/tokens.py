"""REST API tokens. Only the SHA-256 of a token is stored; the token itself is shown once."""

from __future__ import annotations

import datetime as dt
import enum

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column

from db.base import Base, IntId
from db.models._enum import value_enum


class TokenRole(enum.Enum):
    """``viewer`` reads; ``operator`` also starts and aborts runs; ``admin`` also manages tokens."""

    VIEWER = "viewer"
    OPERATOR = "operator"
    ADMIN = "admin"


class ApiToken(IntId, Base):
    """A bearer token: its role, the hex SHA-256 of the secret, a label, the operator it names
    (the person whose actions it signs in a run's audit trail; ``""`` for a token made before
    tokens named one), and revocation."""

    __tablename__ = "api_token"

    role: Mapped[TokenRole] = mapped_column(value_enum(TokenRole, "token_role"))
    token_hash: Mapped[str] = mapped_column(sa.String(64), unique=True)
    label: Mapped[str] = mapped_column(sa.String(200), default="")
    operator: Mapped[str] = mapped_column(sa.String(100), default="", server_default="")
    revoked_at: Mapped[dt.datetime | None]
    last_used_at: Mapped[dt.datetime | None]
