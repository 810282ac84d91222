"""The dashboard: one HTML page whose script reads the JSON API, plus the plot series routes.

``GET /`` serves ``api/static/index.html`` (units, unit history, run pages are client-side
views under ``#/...``); its CSS and JavaScript are the static files mounted at ``/static``.
The page needs no token itself: the browser sends the token the user pasted (kept in
``localStorage``) with every API call, so what it shows is what that token may read.
``GET /channel-colours.css`` gives the plots' channel colours (``--cx``, ``--cy``, ``--cz``)
from :data:`api.plots.colours.CHANNEL_COLOURS`, the one place the Allan PNG and the diagnose
report take them from too.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, HTTPException, status
from fastapi.responses import FileResponse, Response

from api.plots.colours import CHANNEL_COLOURS
from api.routes import plots

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"
INDEX = STATIC_DIR / "index.html"

router = APIRouter()
router.include_router(plots.router)


@router.get("/", include_in_schema=False, response_class=FileResponse)
def index() -> FileResponse:
    """The dashboard page."""
    if not INDEX.is_file():
        raise HTTPException(status.HTTP_500_INTERNAL_SERVER_ERROR, f"dashboard page missing: {INDEX}")
    return FileResponse(INDEX, media_type="text/html", headers={"Cache-Control": "no-cache"})


def channel_colours_css() -> str:
    """``:root`` custom properties ``--cx``, ``--cy``, ``--cz`` with the channel colours."""
    props = "; ".join(f"--c{axis}: {colour}" for axis, colour in zip("xyz", CHANNEL_COLOURS, strict=True))
    return f":root {{ {props}; }}\n"


@router.get("/channel-colours.css", include_in_schema=False)
def channel_colours() -> Response:
    """The channel colours as CSS custom properties (linked by the dashboard page)."""
    return Response(channel_colours_css(), media_type="text/css", headers={"Cache-Control": "no-cache"})
