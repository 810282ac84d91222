"""Wire models of access and health: tokens and their roles, signed links, who the caller is,
and the service's health."""

from __future__ import annotations

import datetime as dt
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from api.schemas.common import stored_text

LINK_PATH_PATTERN = (
    r"^/api/runs/[A-Za-z0-9._~%-]{1,200}/"
    r"(events|certificate\.pdf|export/[a-z-]{1,20}|recording/(csv|sidecar))$"
)


class Health(BaseModel):
    """Liveness and what the service is connected to (the database only by its kind: the
    endpoint needs no token, so it shows no path or host)."""

    status: Literal["ok", "degraded"]
    version: str
    bench: str
    simulated: bool
    database: str = Field(description="the database's kind: sqlite or postgresql")
    database_ok: bool
    busy_run: str | None
    public_read: bool
    certificate_problems: list[str] = Field(
        default_factory=list,
        description="what this bench's certificates lack (settings named); on a real bench the first "
        "three kinds (laboratory name, address, authorising person) stop certificates being issued",
    )
    certificates_blocked: bool = Field(
        default=False,
        description="a real bench that cannot issue certificates until its settings are completed",
    )
    worker: str = Field(
        default="",
        description="random id of the API process that answered (also the X-Calbench-Worker header of "
        "every response), to tell the workers of `calbench serve --workers N` apart",
    )
    live_updates: Literal["notify", "poll"] = Field(
        default="poll",
        description="how this process's event streams learn of a run's changes: notify (PostgreSQL "
        "LISTEN, at once) or poll (every 0.5 s: SQLite, or while the notification connection is down)",
    )


class WhoAmI(BaseModel):
    """The role of the presented token."""

    role: Literal["viewer", "operator", "admin", "anonymous"]


TokenRoleName = Literal["viewer", "operator", "admin"]


class TokenCreate(BaseModel):
    """A new API token: its role and a label saying whose it is."""

    model_config = ConfigDict(extra="forbid")

    role: TokenRoleName
    label: str = Field(default="", max_length=200, description="who or what uses it, e.g. 'wall screen'")
    operator: str = Field(
        default="",
        max_length=100,
        description="the person the token stands for; every run action taken with it is stored under "
        "this name (the run's audit trail); required for operator and admin tokens",
        examples=["Ada Lovelace"],
    )

    @field_validator("label", "operator")
    @classmethod
    def _plain_text(cls, value: str) -> str:
        return (stored_text(value) or "").strip()

    @model_validator(mode="after")
    def _named_when_it_acts(self) -> TokenCreate:
        if self.role in ("operator", "admin") and not self.operator:
            raise ValueError(f"operator: an {self.role} token acts on runs: name the person it stands for")
        return self


class TokenOut(BaseModel):
    """A stored API token (never its secret)."""

    id: int
    role: TokenRoleName
    label: str
    operator: str = Field(default="", description="the person the token stands for")
    created_at: dt.datetime
    last_used_at: dt.datetime | None = None
    revoked_at: dt.datetime | None = None


class TokenCreated(TokenOut):
    """A token just created, with its secret: shown this once, only its SHA-256 is stored."""

    secret: str


class LinkRequest(BaseModel):
    """Ask for a signed link to a resource a browser opens directly."""

    model_config = ConfigDict(extra="forbid")

    path: str = Field(
        pattern=LINK_PATH_PATTERN,
        max_length=300,
        description="/api/runs/{id}/certificate.pdf, /api/runs/{id}/events, /api/runs/{id}/export/{format} "
        "or /api/runs/{id}/recording/{csv,sidecar}",
        examples=["/api/runs/R-20250101-0001/certificate.pdf"],
    )


class LinkOut(BaseModel):
    """A link that works without a token until ``expires_at`` (and while the token it was made
    for is live)."""

    url: str
    expires_at: dt.datetime
