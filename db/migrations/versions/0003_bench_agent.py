"""Bench agents' presence: when a bench's agent last said it was alive, which process it is,
and which procedures its bench can run.

Revision ID: 0003
Revises: 0002
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

import db.types

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

COLUMNS = (
    ("agent_seen_at", db.types.UtcDateTime()),
    ("agent_pid", sa.Integer()),
    ("agent_host", sa.String(255)),
    ("info", sa.JSON()),
)


def upgrade() -> None:
    with op.batch_alter_table("bench") as batch:
        for name, type_ in COLUMNS:
            batch.add_column(sa.Column(name, type_, nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("bench") as batch:
        for name, _type in reversed(COLUMNS):
            batch.drop_column(name)
