"""API tokens in the database (admin only): create (the secret is returned once), list, revoke.

Tokens from ``CALBENCH_TOKENS`` are configuration and are not listed or revocable here.
"""

from __future__ import annotations

from typing import Annotated

import sqlalchemy as sa
from fastapi import APIRouter, HTTPException, Path, status

from api.deps import AdminDep, SessionDep
from api.schemas import TokenCreate, TokenCreated, TokenOut
from bench.inputs import MAX_INT
from db.models import ApiToken, TokenRole
from db.repo.tokens import create_token, list_tokens, revoke_token

router = APIRouter(prefix="/api/tokens", tags=["tokens"])


def token_out(token: ApiToken) -> TokenOut:
    """A stored token without its secret."""
    return TokenOut(
        id=token.id,
        role=token.role.value,
        label=token.label,
        operator=token.operator,
        created_at=token.created_at,
        last_used_at=token.last_used_at,
        revoked_at=token.revoked_at,
    )


@router.post("", status_code=status.HTTP_201_CREATED, response_model=TokenCreated)
def create(body: TokenCreate, session: SessionDep, _: AdminDep) -> TokenCreated:
    """Create a token; the response carries its secret, which is not stored and not shown again."""
    with session.begin():
        token, secret = create_token(session, TokenRole(body.role), body.label, operator=body.operator)
        return TokenCreated(**token_out(token).model_dump(), secret=secret)


@router.get("", response_model=list[TokenOut])
def tokens(session: SessionDep, _: AdminDep) -> list[TokenOut]:
    """Every database token, oldest first, revoked ones included (no secrets)."""
    with session.begin():
        return [token_out(t) for t in list_tokens(session)]


@router.delete(
    "/{token_id}",
    response_model=TokenOut,
    responses={404: {"description": "no such token"}, 409: {"description": "already revoked"}},
)
def revoke(
    token_id: Annotated[int, Path(ge=1, le=MAX_INT, description="the token's id")],
    session: SessionDep,
    _: AdminDep,
) -> TokenOut:
    """Revoke a token: from now on it gets 401. The row is kept (who had access, until when)."""
    with session.begin():
        if not revoke_token(session, token_id):
            token = session.get(ApiToken, token_id)
            if token is None:
                raise HTTPException(status.HTTP_404_NOT_FOUND, f"token {token_id} not found")
            raise HTTPException(
                status.HTTP_409_CONFLICT, f"token {token_id} was revoked at {token.revoked_at}"
            )
        token = session.scalars(
            sa.select(ApiToken).where(ApiToken.id == token_id).execution_options(populate_existing=True)
        ).one()
        return token_out(token)
