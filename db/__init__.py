"""Persistence: SQLAlchemy 2 models, Alembic migrations (SQLite and PostgreSQL), repo, run observer.

Layer rule: may import ``bench`` and ``drivers``, never ``station`` or ``api``; repo functions never
commit (the caller owns the transaction).
"""
