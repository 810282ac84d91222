"""The admin token of a service without ``CALBENCH_TOKENS``: made once, kept across restarts.

At its first start such a service creates an admin token in the database's ``api_token``
table — only its SHA-256 is stored (:func:`db.repo.tokens.create_token`) — and prints the
secret once; every later start finds it and prints where it came from, never the secret
(which it no longer knows). The admin then names the lab's people with their own tokens
(``POST /api/tokens``). Revoking every admin token (``DELETE /api/tokens/{id}``, with a token
of ``CALBENCH_TOKENS`` if the secret is lost) and restarting makes a new one, printed once.
"""

from __future__ import annotations

import dataclasses

import sqlalchemy as sa

from db.engine import make_session_factory
from db.migrate import open_database
from db.models import ApiToken, TokenRole
from db.repo.tokens import create_token

LABEL = "first start of calbench serve"
OPERATOR = "administrator (first-start token)"


@dataclasses.dataclass(frozen=True)
class FirstAdmin:
    """The service's admin token as its start found or made it.

    :param token_id: its ``api_token`` row.
    :param secret: the secret, only when this start created it (print it once); else ``None``.
    """

    token_id: int
    secret: str | None


def first_admin(database_url: str) -> FirstAdmin:
    """The oldest live admin token of the database at ``database_url`` (schema created or
    upgraded first), or a new one when there is none."""
    engine = open_database(database_url)
    try:
        with make_session_factory(engine).begin() as s:
            live = s.scalars(
                sa.select(ApiToken.id)
                .where(ApiToken.role == TokenRole.ADMIN, ApiToken.revoked_at.is_(None))
                .order_by(ApiToken.id)
                .limit(1)
            ).first()
            if live is not None:
                return FirstAdmin(live, None)
            token, secret = create_token(s, TokenRole.ADMIN, LABEL, operator=OPERATOR)
            return FirstAdmin(token.id, secret)
    finally:
        engine.dispose()


def announcement(admin: FirstAdmin) -> str:
    """The line ``calbench serve`` prints about its admin token."""
    if admin.secret is not None:
        return (
            f"calbench serve: no CALBENCH_TOKENS; admin token (api_token {admin.token_id}, stored hashed, "
            f"shown only now: keep it): {admin.secret}"
        )
    return (
        f"calbench serve: no CALBENCH_TOKENS; the admin token printed at the first start holds "
        f"(api_token {admin.token_id}); if its secret is lost, start once with "
        f"CALBENCH_TOKENS=admin:SECRET:NAME, revoke it (DELETE /api/tokens/{admin.token_id}) and "
        "restart without CALBENCH_TOKENS for a new one"
    )
