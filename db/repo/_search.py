"""Case-insensitive "contains" search over text columns, the one rule the lists share."""

from __future__ import annotations

from typing import Any

import sqlalchemy as sa


def contains_any(text: str, *columns: Any) -> sa.ColumnElement[bool]:
    """Rows where any of ``columns`` contains ``text`` (case-insensitive; ``%``, ``_`` and
    ``\\`` in ``text`` match themselves)."""
    pattern = "%" + text.lower().replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_") + "%"
    return sa.or_(*(sa.func.lower(c).like(pattern, escape="\\") for c in columns))
