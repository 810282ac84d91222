"""Bearer tokens with roles: ``viewer`` reads, ``operator`` also writes, ``admin`` also manages.

Tokens come from ``CALBENCH_TOKENS`` (``operator:SECRET,viewer:SECRET,...``) and from the
``api_token`` table (only their SHA-256 is stored). A request presents one as
``Authorization: Bearer SECRET``; the two endpoints a browser opens directly (the event
stream, the PDF) also accept ``?access_token=SECRET``. Missing or unknown token: 401;
a known token whose role is too low: 403. With ``public_read`` reads need no token, but a
token that is presented must still be valid.
"""

from __future__ import annotations

import contextlib
import enum
import hashlib
import logging
import secrets
import threading
import time
from collections.abc import Iterable
from concurrent.futures import ThreadPoolExecutor

from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker

from db.repo.tokens import lookup_token, touch_token

log = logging.getLogger(__name__)
TOUCH_INTERVAL_S = 60.0
"""A database token's ``last_used_at`` is written at most this often (s)."""


class Role(enum.IntEnum):
    """Ordered roles: a higher one may do everything a lower one may."""

    ANONYMOUS = 0
    VIEWER = 1
    OPERATOR = 2
    ADMIN = 3

    @property
    def label(self) -> str:
        """``viewer``, ``operator``, ``admin`` or ``anonymous``."""
        return self.name.lower()


class AuthError(Exception):
    """A request cannot be served for this token.

    :param status_code: 401 (no or unknown token) or 403 (role too low).
    """

    def __init__(self, status_code: int, message: str) -> None:
        super().__init__(message)
        self.status_code = status_code


def _digest(secret: str) -> str:
    return hashlib.sha256(secret.encode("utf-8")).hexdigest()


def parse_tokens(entries: Iterable[str]) -> dict[str, Role]:
    """``["operator:SECRET", ...]`` -> ``{sha256(SECRET): Role}``.

    :raises ValueError: an entry without ``role:``, an unknown role, a secret shorter than
        8 characters, or one secret given two roles (the message names the entry by index).
    """
    table: dict[str, Role] = {}
    for i, entry in enumerate(entries):
        role_text, sep, secret = entry.partition(":")
        where = f"CALBENCH_TOKENS entry {i + 1}"
        if not sep:
            raise ValueError(f"{where}: expected role:SECRET (e.g. operator:abc123...), got no ':'")
        role_name = role_text.strip().lower()
        if role_name not in ("viewer", "operator", "admin"):
            raise ValueError(f"{where}: role {role_text!r} is not viewer, operator or admin")
        secret = secret.strip()
        if len(secret) < 8:
            raise ValueError(f"{where}: the {role_name} secret is shorter than 8 characters")
        digest = _digest(secret)
        if digest in table and table[digest] is not Role[role_name.upper()]:
            raise ValueError(f"{where}: the same secret is already given another role")
        table[digest] = Role[role_name.upper()]
    return table


def new_secret() -> str:
    """A fresh random token secret (URL-safe, 256 bits)."""
    return secrets.token_urlsafe(32)


class Authenticator:
    """Resolves a presented secret to a role.

    Database tokens are looked up in a read-only session (a request never waits for the
    write lock to authenticate); their ``last_used_at`` is written by one background thread,
    at most once per :data:`TOUCH_INTERVAL_S` per token.

    :param env_tokens: ``{sha256: Role}`` from :func:`parse_tokens`.
    :param sessions: writing session factory (``last_used_at``), or ``None`` for no database.
    :param read_sessions: read-only session factory for the look-up (default: ``sessions``).
    :param public_read: anonymous requests may read.
    """

    def __init__(
        self,
        env_tokens: dict[str, Role],
        sessions: sessionmaker[Session] | None = None,
        read_sessions: sessionmaker[Session] | None = None,
        *,
        public_read: bool = False,
    ) -> None:
        self._env = dict(env_tokens)
        self._sessions = sessions
        self._read_sessions = read_sessions or sessions
        self.public_read = public_read
        self._touched: dict[int, float] = {}
        self._touch_lock = threading.Lock()
        self._toucher = ThreadPoolExecutor(max_workers=1, thread_name_prefix="token-last-used")

    def add(self, secret: str, role: Role) -> None:
        """Accept one more secret (e.g. the admin token generated at start)."""
        self._env[_digest(secret)] = role

    def is_env_secret(self, secret: str) -> bool:
        """``secret`` is one of the configured (not database) tokens."""
        return _digest(secret) in self._env

    def role_of(self, secret: str) -> Role | None:
        """The role of ``secret``, or ``None`` when no live token matches."""
        role = self._env.get(_digest(secret))
        if role is not None or self._read_sessions is None:
            return role
        with self._read_sessions.begin() as s:
            token = lookup_token(s, secret)
            if token is None:
                return None
            token_id, role = token.id, Role[token.role.name]
        self._schedule_touch(token_id)
        return role

    def _schedule_touch(self, token_id: int) -> None:
        now = time.monotonic()
        with self._touch_lock:
            last = self._touched.get(token_id)
            if last is not None and now - last < TOUCH_INTERVAL_S:
                return
            self._touched[token_id] = now
        with contextlib.suppress(RuntimeError):  # closed: the service is stopping
            self._toucher.submit(self._touch, token_id)

    def _touch(self, token_id: int) -> None:
        if self._sessions is None:
            return
        try:
            with self._sessions.begin() as s:
                touch_token(s, token_id)
        except SQLAlchemyError:
            log.warning("could not record the use of API token %d", token_id, exc_info=True)

    def close(self) -> None:
        """Finish pending ``last_used_at`` writes and stop the background thread."""
        self._toucher.shutdown(wait=True)

    def require(self, secret: str | None, minimum: Role) -> Role:
        """The role of ``secret`` if it is at least ``minimum``.

        :raises AuthError: 401 for a missing/unknown token, 403 for a role too low.
        """
        if not secret:
            if minimum <= Role.VIEWER and self.public_read:
                return Role.ANONYMOUS
            raise AuthError(401, f"{minimum.label} token required (Authorization: Bearer TOKEN)")
        role = self.role_of(secret)
        if role is None:
            raise AuthError(401, "unknown or revoked token")
        if role < minimum:
            raise AuthError(403, f"this needs the {minimum.label} role; the token is {role.label}")
        return role
