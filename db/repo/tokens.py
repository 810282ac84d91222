"""API tokens: only ``sha256(secret)`` is stored; the secret is returned once, at creation."""

from __future__ import annotations

import datetime as dt
import hashlib
import secrets

import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import ApiToken, TokenRole
from db.types import utc_now


def hash_token(secret: str) -> str:
    """Hex SHA-256 of the token text."""
    return hashlib.sha256(secret.encode("utf-8")).hexdigest()


def create_token(
    session: Session, role: TokenRole | str, label: str = "", *, operator: str = ""
) -> tuple[ApiToken, str]:
    """A new token with ``role`` standing for ``operator`` (a person's name); returns the row and
    the secret (shown once, never stored)."""
    secret = secrets.token_urlsafe(32)
    token = ApiToken(role=TokenRole(role), token_hash=hash_token(secret), label=label, operator=operator)
    session.add(token)
    session.flush()
    return token, secret


def find_token(session: Session, secret: str, *, now: dt.datetime | None = None) -> ApiToken | None:
    """The live (not revoked) token for ``secret``, with ``last_used_at`` updated; else ``None``."""
    token = session.scalars(
        sa.select(ApiToken).where(ApiToken.token_hash == hash_token(secret), ApiToken.revoked_at.is_(None))
    ).one_or_none()
    if token is not None:
        token.last_used_at = now or utc_now()
        session.flush()
    return token


def lookup_token(session: Session, secret: str) -> ApiToken | None:
    """The live (not revoked) token for ``secret``, else ``None``; reads only."""
    return session.scalars(
        sa.select(ApiToken).where(ApiToken.token_hash == hash_token(secret), ApiToken.revoked_at.is_(None))
    ).one_or_none()


def touch_token(session: Session, token_id: int, *, now: dt.datetime | None = None) -> None:
    """Set a token's ``last_used_at``."""
    session.execute(sa.update(ApiToken).where(ApiToken.id == token_id).values(last_used_at=now or utc_now()))


def revoke_token(session: Session, token_id: int, *, now: dt.datetime | None = None) -> bool:
    """Revoke a token; False if it does not exist or was already revoked."""
    result = session.execute(
        sa.update(ApiToken)
        .where(ApiToken.id == token_id, ApiToken.revoked_at.is_(None))
        .values(revoked_at=now or utc_now())
    )
    return bool(getattr(result, "rowcount", 0) == 1)


def list_tokens(session: Session) -> list[ApiToken]:
    """All tokens (hashes only), oldest first."""
    return list(session.scalars(sa.select(ApiToken).order_by(ApiToken.id)))
