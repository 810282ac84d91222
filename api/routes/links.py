"""Signed links: what a browser opens directly (a certificate PDF, a run's event stream)
carries a short-lived link signed by the service, never the caller's token."""

from __future__ import annotations

import datetime as dt
from urllib.parse import quote, unquote

from fastapi import APIRouter, status

from api.deps import ServicesDep, ViewerPrincipalDep
from api.schemas import LinkOut, LinkRequest

router = APIRouter(prefix="/api", tags=["links"])


@router.post("/links", status_code=status.HTTP_201_CREATED, response_model=LinkOut)
def make_link(body: LinkRequest, services: ServicesDep, who: ViewerPrincipalDep) -> LinkOut:
    """A link to ``path`` (a certificate PDF or an event stream) that works without a token for
    a few minutes, for the caller's role, and dies when the caller's token is revoked."""
    link, expires = services.auth.links.sign(unquote(body.path), who)
    return LinkOut(
        url=f"{body.path}?link={quote(link, safe='')}",
        expires_at=dt.datetime.fromtimestamp(expires, dt.UTC),
    )
