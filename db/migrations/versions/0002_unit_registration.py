"""Unit registration: description, customer, date of receipt, nominal scale and zero-g
output, condition.

Revision ID: 0002
Revises: 0001
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0002"
down_revision: str | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

COLUMNS = (
    ("description", sa.String(200)),
    ("customer_name", sa.String(200)),
    ("customer_address", sa.String(500)),
    ("received_on", sa.Date()),
    ("nominal_scale", sa.Float()),
    ("nominal_bias", sa.Float()),
    ("condition", sa.String(500)),
)


def upgrade() -> None:
    with op.batch_alter_table("unit") as batch:
        for name, type_ in COLUMNS:
            batch.add_column(sa.Column(name, type_, nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("unit") as batch:
        for name, _type in reversed(COLUMNS):
            batch.drop_column(name)
