"""The REST routers, aggregated in :data:`api_router`."""

from __future__ import annotations

from fastapi import APIRouter

from api.routes import (
    benches,
    certificates,
    drift,
    health,
    links,
    plans,
    procedures,
    recordings,
    runs,
    tokens,
    units,
)

api_router = APIRouter()
for _module in (
    health,
    runs,
    benches,
    procedures,
    plans,
    certificates,
    units,
    recordings,
    drift,
    tokens,
    links,
):
    api_router.include_router(_module.router)
